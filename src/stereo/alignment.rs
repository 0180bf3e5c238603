//! Residual misalignment of a nearly rectified pair, measured from a disparity estimate.
//!
//! Pairs rectified from an imperfect calibration (Middlebury 2014's "imperfect" scenes; most
//! cameras after a knock) keep a vertical offset of a fraction of a pixel that changes slowly
//! across the image. Census costs and the local sub-pixel fit compare rows, so such an offset
//! costs accuracy everywhere. [`estimate_residual`] measures it at textured pixels whose disparity
//! is known roughly (the coarse level's), far cheaper than the search of
//! [`super::rectify::estimate_misalignment`], whose range (±8 px) it does not need, and
//! [`VerticalResidual::apply`] undoes it by resampling the right view along columns only (a
//! horizontal shift is a disparity, which matching finds anyway).

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::image::Raster;
use crate::robust::{tukey, MAD_TO_SIGMA, TUKEY_C};

/// The vertical position of the right view's content relative to the left's, an affine function
/// of the pixel: `v(x, y) = offset + per_column · (x − w/2) + per_row · (y − h/2)` pixels
/// (positive: lower in the right view). `per_column` is a small rotation (radians), `per_row` a
/// vertical scale difference.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct VerticalResidual {
    /// Offset at the image centre, pixels.
    pub offset: f32,
    /// Change per pixel to the right, pixels per pixel.
    pub per_column: f32,
    /// Change per pixel down, pixels per pixel.
    pub per_row: f32,
}

impl VerticalResidual {
    /// The offset at pixel (x, y) of an image `w × h`, pixels.
    pub fn at(&self, x: f32, y: f32, w: usize, h: usize) -> f32 {
        self.offset + self.per_column * (x - w as f32 / 2.0) + self.per_row * (y - h as f32 / 2.0)
    }

    /// Largest offset over an image `w × h` (at a corner), pixels.
    pub fn largest(&self, w: usize, h: usize) -> f32 {
        self.offset.abs()
            + self.per_column.abs() * w as f32 / 2.0
            + self.per_row.abs() * h as f32 / 2.0
    }

    /// `right` resampled so that its content lies on the left view's rows: pixel (x, y) takes
    /// `right(x, y + v(x, y))`, Catmull–Rom along the column (sharper than bilinear), rows beyond
    /// the image replicated.
    pub fn apply(&self, right: &Raster<u8>) -> Raster<u8> {
        let (w, h) = (right.width(), right.height());
        if w == 0 || h == 0 {
            return right.clone();
        }
        let mut out = vec![0u8; w * h];
        out.par_chunks_mut(w).enumerate().for_each_init(
            || vec![0f32; w],
            |source_y, (y, row)| {
                for (x, sy) in source_y.iter_mut().enumerate() {
                    *sy = y as f32 + self.at(x as f32, y as f32, w, h);
                }
                // The source row changes slowly along a row (the offset is nearly constant):
                // over each run of pixels with the same four source rows the interpolation is a
                // plain loop the compiler vectorises, instead of four clamped reads per pixel.
                let mut start = 0;
                while start < w {
                    let y0 = source_y[start].floor();
                    // At least one pixel per run, so a NaN offset cannot stall the loop.
                    let end = start
                        + 1
                        + source_y[start + 1..]
                            .iter()
                            .position(|sy| sy.floor() != y0)
                            .unwrap_or(w - start - 1);
                    let source = |k: f32| {
                        let yy = (y0 + k).clamp(0.0, (h - 1) as f32) as usize;
                        &right.row(yy)[start..end]
                    };
                    resample_run(
                        [source(-1.0), source(0.0), source(1.0), source(2.0)],
                        &source_y[start..end],
                        y0,
                        &mut row[start..end],
                    );
                    start = end;
                }
            },
        );
        Raster::from_vec(w, h, out)
    }
}

/// Catmull–Rom between rows `rows[1]` and `rows[2]` at the fractions `source_y − y0`, rounded to
/// grey levels.
fn resample_run(rows: [&[u8]; 4], source_y: &[f32], y0: f32, out: &mut [u8]) {
    let [r0, r1, r2, r3] = rows;
    for (((((o, &sy), &a), &b), &c), &d) in
        out.iter_mut().zip(source_y).zip(r0).zip(r1).zip(r2).zip(r3)
    {
        let t = sy - y0;
        let (p0, p1, p2, p3) = (a as f32, b as f32, c as f32, d as f32);
        let v = p1
            + 0.5
                * t
                * (p2 - p0
                    + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + t * (3.0 * (p1 - p2) + p3 - p0)));
        *o = (v + 0.5).clamp(0.0, 255.0) as u8;
    }
}

/// Largest residual vertical offset measured, pixels; a sample whose match lies farther is
/// dropped (larger offsets need `correct_misalignment`).
pub const MAX_RESIDUAL_OFFSET: f32 = 2.0;

/// Window half-size of a sample, pixels (window 7×7).
const RADIUS: usize = 3;

/// Distance between samples, pixels, in x and in y.
const GRID: usize = 8;

/// Gauss–Newton steps per sample.
const ITERATIONS: usize = 6;

/// Fewest accepted samples for an estimate.
const MIN_SAMPLES: usize = 64;

/// One sample: where the right view's content matching left pixel (x, y) sits vertically.
#[derive(Debug, Clone, Copy)]
struct Shift {
    /// Right-view column of the match, pixels.
    x: f32,
    /// Row of the left pixel.
    y: f32,
    /// Vertical offset of the match, pixels (positive: lower in the right view).
    v: f32,
}

/// The vertical misalignment of `right` relative to `left` from `disparity`: a rough disparity of
/// the left view with `scale` left pixels per pixel (2 for the half-size level), NaN where
/// unknown.
///
/// At a grid of left pixels with texture in both directions, a two-dimensional Lucas–Kanade fit
/// (inverse compositional, window mean and contrast removed so exposure changes do not matter)
/// finds where the window lies in the right view near `(x − d, y)`; a robust plane fit (Tukey
/// weights) of the vertical shifts against the right-view column and the row gives the
/// [`VerticalResidual`].
/// `None` when fewer than 64 samples converge (textureless or tiny images).
pub fn estimate_residual(
    left: &Raster<u8>,
    right: &Raster<u8>,
    disparity: &Raster<f32>,
    scale: usize,
) -> Option<VerticalResidual> {
    let (w, h) = (left.width(), left.height());
    let margin = RADIUS + 2 + MAX_RESIDUAL_OFFSET.ceil() as usize;
    if w < 2 * margin + 1 || h < 2 * margin + 1 || scale == 0 {
        return None;
    }
    let rows: Vec<usize> = (margin..h - margin).step_by(GRID).collect();
    let shifts: Vec<Shift> = rows
        .par_iter()
        .flat_map_iter(|&y| {
            (margin..w - margin).step_by(GRID).filter_map(move |x| {
                let (cx, cy) = (
                    (x / scale).min(disparity.width() - 1),
                    (y / scale).min(disparity.height() - 1),
                );
                let d = *disparity.get(cx, cy) * scale as f32;
                track_fast(left, right, x, y, d)
            })
        })
        .collect();
    if shifts.len() < MIN_SAMPLES {
        return None;
    }
    robust_plane(&shifts, w as f32 / 2.0, h as f32 / 2.0)
}

/// Pixels per side of a sample's window.
const SIDE: usize = 2 * RADIUS + 1;

/// Pixels in a sample's window.
const N: usize = SIDE * SIDE;

/// Values per stored window row: the row's `SIDE` pixels and weightless padding, so that every
/// loop over a window runs on whole 8-lane registers.
const LANES: usize = 8;

// A row and its padding fit the lanes, and the padding's pixel (read for the bilinear weights
// of the whole row) lies within the reach that `track` keeps from the image's borders.
const _: () = assert!(SIDE < LANES && LANES - RADIUS <= RADIUS + 2);

/// A window, row by row, each row padded to [`LANES`] values.
type Window = [f32; SIDE * LANES];

/// 1 for a window's pixels, 0 for the padding.
const PIXELS: Window = {
    let mut mask = [0f32; SIDE * LANES];
    let mut k = 0;
    while k < mask.len() {
        if k % LANES < SIDE {
            mask[k] = 1.0;
        }
        k += 1;
    }
    mask
};

crate::avx2_variant!(fn track_fast<'a>(left: &'a Raster<u8>, right: &'a Raster<u8>, x: usize, y: usize, d: f32) -> Option<Shift> => track);

/// The vertical shift of left pixel (x, y)'s window in the right view, starting at `x − d`.
#[inline(always)]
fn track(left: &Raster<u8>, right: &Raster<u8>, x: usize, y: usize, d: f32) -> Option<Shift> {
    let (w, h) = (right.width() as f32, right.height() as f32);
    let start = x as f32 - d;
    let reach = (RADIUS + 2) as f32;
    if !start.is_finite() || start < reach || start > w - 1.0 - reach {
        return None;
    }
    // Template: the left window, mean and contrast removed, and its gradients; their padding
    // stays 0, so it adds nothing to any sum below.
    let mut t: Window = [0.0; SIDE * LANES];
    let mut gx: Window = [0.0; SIDE * LANES];
    let mut gy: Window = [0.0; SIDE * LANES];
    // The window's rows, with one pixel more on each side for the gradients.
    let row = |j: usize| &left.row(y + j - RADIUS)[x - RADIUS - 1..x + RADIUS + 2];
    for j in 0..SIDE {
        for (v, &p) in t[j * LANES..j * LANES + SIDE].iter_mut().zip(&row(j)[1..]) {
            *v = p as f32;
        }
    }
    // Most samples without texture stop here, before their gradients are taken.
    let (mean, sd) = mean_sd(&t);
    if sd < 2.0 {
        return None;
    }
    let above = |j: usize| &left.row(y + j - RADIUS - 1)[x - RADIUS..=x + RADIUS];
    let below = |j: usize| &left.row(y + j - RADIUS + 1)[x - RADIUS..=x + RADIUS];
    for j in 0..SIDE {
        let (r, up, down) = (row(j), above(j), below(j));
        for i in 0..SIDE {
            gx[j * LANES + i] = 0.5 * (r[i + 2] as f32 - r[i] as f32);
            gy[j * LANES + i] = 0.5 * (down[i] as f32 - up[i] as f32);
        }
    }
    for k in 0..t.len() {
        t[k] = (t[k] - mean) / sd * PIXELS[k];
        gx[k] /= sd;
        gy[k] /= sd;
    }
    // Hessian of the template (constant in the inverse compositional form).
    let hxx = lane_sum(&std::array::from_fn(|k| gx[k] * gx[k]));
    let hxy = lane_sum(&std::array::from_fn(|k| gx[k] * gy[k]));
    let hyy = lane_sum(&std::array::from_fn(|k| gy[k] * gy[k]));
    let det = hxx * hyy - hxy * hxy;
    // Texture in both directions: the smaller eigenvalue of the Hessian.
    let trace = hxx + hyy;
    let min_eig = 0.5 * (trace - ((hxx - hyy).powi(2) + 4.0 * hxy * hxy).sqrt());
    if min_eig < 0.05 * N as f32 || det <= 0.0 {
        return None;
    }
    let (mut u, mut v) = (start, y as f32);
    let mut r: Window = [0.0; SIDE * LANES];
    for _ in 0..ITERATIONS {
        // One fraction for the whole window: bilinear weights once, then rows read as slices
        // (the padding lane too: `reach` keeps its pixel inside the image).
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (x0, y0) = (x0 as usize - RADIUS, y0 as usize - RADIUS);
        // The reach checks above are in `f32`; these are exact (and hold unless an image is
        // wider or taller than `f32` counts pixels exactly).
        if x0 + LANES + 1 > right.width() || y0 + SIDE + 1 > right.height() {
            return None;
        }
        for j in 0..SIDE {
            let top = &right.row(y0 + j)[x0..x0 + LANES + 1];
            let bottom = &right.row(y0 + j + 1)[x0..x0 + LANES + 1];
            for i in 0..LANES {
                let a = top[i] as f32 + fx * (top[i + 1] as f32 - top[i] as f32);
                let b = bottom[i] as f32 + fx * (bottom[i + 1] as f32 - bottom[i] as f32);
                r[j * LANES + i] = (a + fy * (b - a)) * PIXELS[j * LANES + i];
            }
        }
        let (rm, rs) = mean_sd(&r);
        if rs < 1.0 {
            return None;
        }
        // The padding's error is multiplied by gradients of 0.
        let e: Window = std::array::from_fn(|k| (r[k] - rm) / rs - t[k]);
        let ex = lane_sum(&std::array::from_fn(|k| gx[k] * e[k]));
        let ey = lane_sum(&std::array::from_fn(|k| gy[k] * e[k]));
        let du = (hyy * ex - hxy * ey) / det;
        let dv = (hxx * ey - hxy * ex) / det;
        if !(du.is_finite() && dv.is_finite()) {
            return None;
        }
        u -= du.clamp(-1.0, 1.0);
        v -= dv.clamp(-1.0, 1.0);
        let off = v - y as f32;
        if off.abs() > MAX_RESIDUAL_OFFSET
            || (u - start).abs() > 2.0
            || u < reach
            || u > w - 1.0 - reach
            || v < reach
            || v > h - 1.0 - reach
        {
            return None;
        }
        if du.abs() < 0.01 && dv.abs() < 0.01 {
            return Some(Shift {
                x: u,
                y: y as f32,
                v: off,
            });
        }
    }
    None
}

/// The sum of a window's values, lane by lane over the rows and then across the lanes: a sum the
/// compiler keeps in vector registers (it may not reorder a plain running sum of floats).
#[inline(always)]
fn lane_sum(v: &Window) -> f32 {
    let mut lanes = [0f32; LANES];
    for row in v.chunks_exact(LANES) {
        for (l, &x) in lanes.iter_mut().zip(row) {
            *l += x;
        }
    }
    lanes.iter().sum()
}

/// Mean and standard deviation of a window's pixels (its padding must be 0).
#[inline(always)]
fn mean_sd(v: &Window) -> (f32, f32) {
    let mean = lane_sum(v) / N as f32;
    let var = lane_sum(&std::array::from_fn(|k| (v[k] - mean).powi(2) * PIXELS[k])) / N as f32;
    (mean, var.sqrt())
}

/// `v ≈ offset + per_column · (x − cx) + per_row · (y − cy)` fitted with Tukey's biweight
/// (iteratively reweighted least squares from the median, scale from the median absolute
/// deviation).
fn robust_plane(samples: &[Shift], cx: f32, cy: f32) -> Option<VerticalResidual> {
    // Medians by selection, not a sort of every sample (nine of them per pair).
    let median = |mut v: Vec<f32>| {
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    let mut fit = VerticalResidual {
        offset: median(samples.iter().map(|s| s.v).collect()),
        ..Default::default()
    };
    let residual = |f: &VerticalResidual, s: &Shift| {
        s.v - f.offset - f.per_column * (s.x - cx) - f.per_row * (s.y - cy)
    };
    for _ in 0..8 {
        let mad = median(samples.iter().map(|s| residual(&fit, s).abs()).collect());
        // Tukey's usual cut-off with σ from the MAD; at least 0.1 px.
        let cut = (TUKEY_C * MAD_TO_SIGMA * mad as f64).max(0.1);
        let (mut normal, mut rhs) = (DMat3::ZERO, DVec3::ZERO);
        for s in samples {
            let wgt = tukey(residual(&fit, s) as f64, cut);
            if wgt == 0.0 {
                continue;
            }
            let j = DVec3::new(1.0, (s.x - cx) as f64, (s.y - cy) as f64);
            normal += DMat3::from_cols(j * j.x, j * j.y, j * j.z) * wgt;
            rhs += j * (wgt * s.v as f64);
        }
        if normal.determinant().abs() < 1e-9 {
            return None;
        }
        let p = normal.inverse() * rhs;
        fit = VerticalResidual {
            offset: p.x as f32,
            per_column: p.y as f32,
            per_row: p.z as f32,
        };
    }
    let finite = fit.offset.is_finite() && fit.per_column.is_finite() && fit.per_row.is_finite();
    finite.then_some(fit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stereo::tests::texture;

    /// A textured plane at disparity 6 whose right view sits `truth.at(x, y)` lower.
    fn pair(truth: VerticalResidual) -> (Raster<u8>, Raster<u8>, Raster<f32>) {
        let (w, h) = (160, 120);
        let left = Raster::from_fn(w, h, |x, y| texture(x as f32, y as f32));
        let right = Raster::from_fn(w, h, |x, y| {
            let (xf, yf) = (x as f32, y as f32);
            texture(xf + 6.0, yf - truth.at(xf, yf, w, h))
        });
        (left, right, Raster::filled(w / 2, h / 2, 3.0f32))
    }

    #[test]
    fn finds_offset_rotation_and_scale_to_a_few_hundredths_of_a_pixel() {
        for truth in [
            VerticalResidual {
                offset: 0.4,
                ..Default::default()
            },
            VerticalResidual {
                offset: -0.7,
                per_column: 0.003,
                per_row: -0.004,
            },
            VerticalResidual::default(),
        ] {
            let (l, r, coarse) = pair(truth);
            let est = estimate_residual(&l, &r, &coarse, 2).expect("textured pair");
            for (x, y) in [(0.0, 0.0), (159.0, 0.0), (0.0, 119.0), (159.0, 119.0)] {
                let err = est.at(x, y, 160, 120) - truth.at(x, y, 160, 120);
                assert!(err.abs() < 0.06, "{truth:?}: {est:?} at ({x}, {y})");
            }
            // Undoing it puts the right view's rows back on the left's.
            let fixed = est.apply(&r);
            let (_, aligned, _) = pair(VerticalResidual::default());
            let mean_err = (0..160 * 120)
                .filter(|p| (10..110).contains(&(p / 160)))
                .map(|p| fixed.pixels()[p].abs_diff(aligned.pixels()[p]) as f32)
                .sum::<f32>()
                / (160.0 * 100.0);
            assert!(mean_err < 6.0, "{truth:?}: mean grey error {mean_err}");
        }
    }

    #[test]
    fn resampling_matches_the_plain_interpolation_of_each_pixel() {
        let (w, h) = (53, 17);
        let right = Raster::from_fn(w, h, |x, y| ((x * 37 + y * 91) % 256) as u8);
        let plain = |m: &VerticalResidual, x: usize, y: usize| {
            let sy = y as f32 + m.at(x as f32, y as f32, w, h);
            let y0 = sy.floor();
            let t = sy - y0;
            let at = |k: f32| *right.get(x, (y0 + k).clamp(0.0, (h - 1) as f32) as usize) as f32;
            let (p0, p1, p2, p3) = (at(-1.0), at(0.0), at(1.0), at(2.0));
            let v = p1
                + 0.5
                    * t
                    * (p2 - p0
                        + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3
                            + t * (3.0 * (p1 - p2) + p3 - p0)));
            (v + 0.5).clamp(0.0, 255.0) as u8
        };
        // Rows beyond both edges, a source row that changes many times along a row, a whole
        // number of pixels, and a NaN offset (which must still finish).
        for m in [
            VerticalResidual {
                offset: 0.3,
                per_column: 0.07,
                per_row: -0.02,
            },
            VerticalResidual {
                offset: -1.6,
                per_column: -0.011,
                per_row: 0.05,
            },
            VerticalResidual {
                offset: 2.0,
                ..Default::default()
            },
            VerticalResidual {
                offset: f32::NAN,
                ..Default::default()
            },
        ] {
            // An empty view stays empty.
            assert_eq!(m.apply(&Raster::filled(0, 3, 0u8)).width(), 0);
            let out = m.apply(&right);
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(*out.get(x, y), plain(&m, x, y), "{m:?} at ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn flat_tiny_or_unknown_input_gives_none() {
        let flat = Raster::filled(100, 80, 128u8);
        let d = Raster::filled(50, 40, 2.0f32);
        assert!(estimate_residual(&flat, &flat, &d, 2).is_none());
        let tiny = Raster::filled(8, 8, 3u8);
        assert!(estimate_residual(&tiny, &tiny, &Raster::filled(4, 4, 0.0), 2).is_none());
        let (l, r, _) = pair(VerticalResidual::default());
        assert!(estimate_residual(&l, &r, &Raster::filled(80, 60, f32::NAN), 2).is_none());
    }
}
