//! Normals that survive depth noise: at each sample, a plane fitted robustly to the *inverse*
//! depth of a neighbourhood that grows until the normal is well determined.
//!
//! ## Why inverse depth
//! Seen through a pinhole, a plane `n · p = D` has inverse depth `w = 1/Z` that is an *affine*
//! function of the pixel: with `r(u, v) = ((u − cx)/fx, −(v − cy)/fy, −1)` and `p = Z·r`,
//! `w = n · r(u, v) / D = α·u + β·v + γ`. So a plane fit is a linear least-squares problem in
//! `(u, v) → w`, the pixel coordinates are exact, and all the error sits in `w`. For stereo depth
//! that error is also *homoscedastic*: `Z = f·B/d` gives `w = d/(f·B)`, so a constant disparity
//! noise `σ_d` is a constant `σ_w = σ_d/(f·B)` (the familiar `σ_Z ≈ Z²·σ_d/(f·B)`). The normal is
//! then `n ∝ (−α·fx, β·fy, γ + α·cx + β·cy)` (oriented towards the camera).
//!
//! ## The fit
//! `σ_w`, and how far its errors are correlated, are estimated once per depth map
//! ([`correlated_noise`]). Each sample starts from the best supported (within a 5×5 window) of
//! three planes through it: constant inverse depth, the least-squares plane of its 3×3, or the
//! plane of its mesh triangles. Then, for radii 2, 4, 8, 16, 32 pixels (windows thinned to at most
//! 17×17 samples), iteratively reweighted least squares with Tukey's biweight on the residual in
//! units of `σ_w` refits the plane. The weights are measured against the sample's own plane, so a
//! neighbour across a depth discontinuity (or a stereo outlier) gets weight 0: the fit is
//! edge-aware without a separate edge test. Growth stops once the normal's standard error (from
//! the fit's covariance, inflated where samples lie closer than the noise's correlation length)
//! is below [`TARGET_NORMAL_ERROR_DEG`]; on exact depth that is at once, so noise-free input keeps
//! its local normals.

use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::image::Raster;
use crate::robust::{MAD_TO_SIGMA, TUKEY_C};

/// Radii of the growing neighbourhood, pixels.
const RADII: [i64; 5] = [2, 4, 8, 16, 32];
/// A window of radius `r` is sampled every `max(1, r / SUBSAMPLE_DIVISOR)` pixels (≤ 17×17 samples).
const SUBSAMPLE_DIVISOR: i64 = 8;
/// Reweighting rounds at the first radius (where the start may be far off); one round at each
/// larger radius, whose weights come from the previous radius' plane.
const FIRST_RADIUS_ROUNDS: usize = 2;
/// Growth stops once the normal's standard error is below this, degrees.
pub(crate) const TARGET_NORMAL_ERROR_DEG: f64 = 1.0;
/// Samples summed side by side in [`LocalFitter::window_sums`] (eight f32 = one AVX2 register).
const LANES: usize = 8;
/// Sum of weights below which a fit is not trusted (the previous radius' fit stands).
const MIN_WEIGHT: f64 = 8.0;
/// Smallest noise assumed, relative to the median inverse depth: exact (rendered or synthetic)
/// depth still carries f32 rounding, and Tukey's weights need a scale above zero.
const MIN_RELATIVE_NOISE: f64 = 1e-4;

/// The inverse-depth map `w = 1/Z` (1/m) of a depth map, NaN where depth is missing.
pub(crate) fn inverse_depth(depth: &Raster<f32>) -> Raster<f64> {
    depth.map(|&z| {
        if z.is_finite() && z > 0.0 {
            let w = 1.0 / z as f64;
            if w.is_finite() && w > 0.0 {
                return w;
            }
        }
        f64::NAN
    })
}

/// Robust estimate of the inverse-depth noise `σ_w` (1/m): from second differences
/// `w(x − s) − 2·w(x) + w(x + s)` along rows and columns (zero on any plane, since `w` is affine
/// there; `√6·σ_w` standard deviation under white noise), as `1.4826 · median / √6`. Never below
/// [`MIN_RELATIVE_NOISE`] of the median `w`. `None` when fewer than 16 triples are valid.
pub(crate) fn inverse_depth_noise(w: &Raster<f64>, spacing: usize) -> Option<f64> {
    let raw = second_difference_noise(w, spacing)?;
    floored_noise(raw, noise_floor(w))
}

/// [`inverse_depth_noise`] before its floor: `None` when fewer than 16 triples are valid.
fn second_difference_noise(w: &Raster<f64>, spacing: usize) -> Option<f64> {
    let (width, height) = (w.width(), w.height());
    let s = spacing.max(1);
    // Rows in parallel: the median does not depend on the order the differences come in.
    let mut d2: Vec<f64> = (0..height)
        .into_par_iter()
        .flat_map_iter(|y| {
            let mut row = Vec::new();
            for x in 0..width {
                let c = *w.get(x, y);
                if !c.is_finite() {
                    continue;
                }
                if x >= s && x + s < width {
                    let v = *w.get(x - s, y) - 2.0 * c + *w.get(x + s, y);
                    if v.is_finite() {
                        row.push(v.abs());
                    }
                }
                if y >= s && y + s < height {
                    let v = *w.get(x, y - s) - 2.0 * c + *w.get(x, y + s);
                    if v.is_finite() {
                        row.push(v.abs());
                    }
                }
            }
            row
        })
        .collect();
    if d2.len() < 16 {
        return None;
    }
    let k = d2.len() / 2;
    Some(MAD_TO_SIGMA * *d2.select_nth_unstable_by(k, f64::total_cmp).1 / 6f64.sqrt())
}

/// The smallest noise assumed for `w`: [`MIN_RELATIVE_NOISE`] of its median finite value (0
/// without one).
fn noise_floor(w: &Raster<f64>) -> f64 {
    let mut values: Vec<f64> = w
        .pixels()
        .iter()
        .copied()
        .filter(|c| c.is_finite())
        .collect();
    if values.is_empty() {
        return 0.0;
    }
    let k = values.len() / 2;
    MIN_RELATIVE_NOISE * *values.select_nth_unstable_by(k, f64::total_cmp).1
}

/// `raw` raised to `floor`; `None` unless the result is finite and positive.
fn floored_noise(raw: f64, floor: f64) -> Option<f64> {
    let sigma = raw.max(floor);
    (sigma.is_finite() && sigma > 0.0).then_some(sigma)
}

/// `w ≈ a·(u − u₀) + b·(v − v₀) + g` around a centre pixel `(u₀, v₀)`.
#[derive(Clone, Copy, Debug, Default)]
struct LocalPlane {
    a: f64,
    b: f64,
    g: f64,
}

/// Normal of the local plane at pixel centre `(u0, v0)`, unit and facing the camera.
fn normal_of(plane: &LocalPlane, camera: &Camera, u0: f64, v0: f64) -> Option<DVec3> {
    let n = unnormalised_normal(plane, camera, u0, v0);
    n.try_normalize()
}

fn unnormalised_normal(plane: &LocalPlane, camera: &Camera, u0: f64, v0: f64) -> DVec3 {
    let (fx, fy) = (camera.fx as f64, camera.fy as f64);
    let (cx, cy) = (camera.cx as f64, camera.cy as f64);
    DVec3::new(
        -plane.a * fx,
        plane.b * fy,
        plane.g + plane.a * (cx - u0) + plane.b * (cy - v0),
    )
}

/// The local plane through `(u0, v0)` at inverse depth `w0` with unit normal `n` (camera frame).
fn plane_from_normal(n: DVec3, w0: f64, camera: &Camera, u0: f64, v0: f64) -> Option<LocalPlane> {
    let (fx, fy) = (camera.fx as f64, camera.fy as f64);
    let (cx, cy) = (camera.cx as f64, camera.cy as f64);
    let r0 = DVec3::new((u0 - cx) / fx, -(v0 - cy) / fy, -1.0);
    // w = n·r/D with D fixed by w(u0, v0) = w0.
    let nr = n.dot(r0);
    if nr.abs() < 1e-12 {
        return None;
    }
    let inv_d = w0 / nr;
    let plane = LocalPlane {
        a: n.x / fx * inv_d,
        b: -n.y / fy * inv_d,
        g: w0,
    };
    (plane.a.is_finite() && plane.b.is_finite()).then_some(plane)
}

/// Spacings (pixels) of the second differences [`correlated_noise`] compares: stereo errors are
/// correlated over the matcher's windows and smoothing, so short differences cancel most of them.
const NOISE_LADDER: [usize; 5] = [1, 2, 4, 8, 16];
/// Doubling the spacing multiplies second differences by 4 on a curved surface (they grow as the
/// spacing squared) but by at most 2 on correlated noise; above this ratio the growth is taken to
/// be the surface's curvature, not its noise, and the ladder stops.
const CURVATURE_RATIO: f64 = 2.8;

/// Inverse-depth noise and how far it is correlated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct NoiseScale {
    /// Standard deviation `σ_w`, 1/m.
    pub(crate) sigma: f64,
    /// Distance over which errors are correlated, pixels (1 for white noise).
    pub(crate) correlation_px: f64,
}

/// Robust `σ_w` of a depth map whose errors may be correlated between neighbouring pixels: second
/// differences are measured at spacings 1, 2, 4, 8 and 16 ([`inverse_depth_noise`] at each). On
/// white noise they are equal; on correlated noise they grow with the spacing up to the
/// correlation length and then level off (measured on a 128-spp `room` render through our
/// matcher: 0.03 px of disparity at spacings 1–2, 0.145 px at 16, where the true error's spread
/// is 0.149 px).
/// `σ_w` is the largest of them before curvature takes over ([`CURVATURE_RATIO`]); the
/// correlation length is the smallest spacing that reaches half of it. `None` as for
/// [`inverse_depth_noise`].
pub(crate) fn correlated_noise(w: &Raster<f64>) -> Option<NoiseScale> {
    let floor = noise_floor(w);
    let noise_at = |spacing| floored_noise(second_difference_noise(w, spacing)?, floor);
    let mut sigma = noise_at(NOISE_LADDER[0])?;
    let mut ladder = vec![(NOISE_LADDER[0], sigma)];
    for &spacing in &NOISE_LADDER[1..] {
        let Some(next) = noise_at(spacing) else {
            break;
        };
        if next > CURVATURE_RATIO * ladder[ladder.len() - 1].1 {
            break;
        }
        ladder.push((spacing, next));
        sigma = sigma.max(next);
    }
    let correlation_px = ladder
        .iter()
        .find(|&&(_, s)| s >= 0.5 * sigma)
        .map_or(1, |&(spacing, _)| spacing) as f64;
    Some(NoiseScale {
        sigma,
        correlation_px,
    })
}

/// Weighted sums over a window's samples `(du, dv, w)`: the normal equations of the plane fit
/// `w ≈ a·du + b·dv + g`.
#[derive(Clone, Copy, Debug, Default)]
struct WindowSums {
    weight: f64,
    du: f64,
    dv: f64,
    du_du: f64,
    du_dv: f64,
    dv_dv: f64,
    w: f64,
    du_w: f64,
    dv_w: f64,
}

crate::avx2_variant!(fn weight_sums<'a, 'b>(fitter: &'b LocalFitter<'a>, x0: usize, y0: usize, r: i64, plane: Option<&'b LocalPlane>) -> WindowSums => LocalFitter::window_sums::<false>);
crate::avx2_variant!(fn moment_sums<'a, 'b>(fitter: &'b LocalFitter<'a>, x0: usize, y0: usize, r: i64, plane: Option<&'b LocalPlane>) -> WindowSums => LocalFitter::window_sums::<true>);

/// A window's samples: `count` columns from `start` in the padded row of its step's thinned
/// copy (at `du = i·step − r` from the centre, `r` the window's radius), and rows
/// `y_start + j·step`, `j < rows`, at `dv = dv0 + j·step`.
struct Window<'t> {
    thinned: &'t Thinned,
    phase: usize,
    start: usize,
    count: usize,
    y_start: usize,
    dv0: f64,
    rows: usize,
}

impl Window<'_> {
    /// `(y, dv)` of each row.
    #[inline(always)]
    fn rows(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        (0..self.rows).map(|j| {
            let offset = j * self.thinned.step;
            (self.y_start + offset, self.dv0 + offset as f64)
        })
    }

    /// Row `y`'s samples in whole lanes, the window's `count` and then as many past it as fill
    /// the last lane (the caller masks them): inverse depths (0 where missing) and whether each
    /// is valid (1 or 0; 0 outside the image).
    #[inline(always)]
    fn row(&self, y: usize) -> (&[f32], &[f32]) {
        let lanes = self.count.div_ceil(LANES) * LANES;
        let (w, valid) = self.thinned.row(self.phase, y);
        let range = self.start..self.start + lanes;
        (&w[range.clone()], &valid[range])
    }
}

/// Every `step`-th column of the inverse-depth map, one copy per phase (`x ≡ phase mod step`),
/// each row padded with [`THINNED_PAD`] missing samples on both sides: a thinned window then
/// reads one contiguous slice per row, with no bounds test per sample. Missing depth is stored
/// as 0 with a validity of 0, so the fit can weigh it with arithmetic instead of branches. Held
/// in `f32`: its rounding (6·10⁻⁸ relative) is far below the noise floor
/// [`MIN_RELATIVE_NOISE`], and it halves the memory the copies take and stream.
struct Thinned {
    step: usize,
    /// Per phase: the padded row length, the inverse depths and their validity (1 or 0).
    phases: Vec<(usize, Vec<f32>, Vec<f32>)>,
}

/// Padding of a [`Thinned`] row: a window reaches [`SUBSAMPLE_DIVISOR`] samples past an edge,
/// plus up to `LANES − 1` masked ones.
const THINNED_PAD: usize = SUBSAMPLE_DIVISOR as usize + LANES;

impl Thinned {
    fn new(w: &Raster<f64>, step: usize) -> Thinned {
        let (width, height) = (w.width(), w.height());
        let phases = (0..step)
            .map(|phase| {
                let cols = width.saturating_sub(phase).div_ceil(step);
                let stride = cols + 2 * THINNED_PAD;
                let mut values = vec![0.0; stride * height];
                let mut valid = vec![0.0; stride * height];
                values
                    .par_chunks_exact_mut(stride)
                    .zip(valid.par_chunks_exact_mut(stride))
                    .enumerate()
                    .for_each(|(y, (values, valid))| {
                        let inside = THINNED_PAD..THINNED_PAD + cols;
                        for ((value, ok), &v) in values[inside.clone()]
                            .iter_mut()
                            .zip(&mut valid[inside])
                            .zip(w.row(y).iter().skip(phase).step_by(step))
                        {
                            // An inverse depth beyond f32 (a depth under 10⁻³⁸ m) counts as missing.
                            let v = v as f32;
                            if v.is_finite() {
                                (*value, *ok) = (v, 1.0);
                            }
                        }
                    });
                (stride, values, valid)
            })
            .collect();
        Thinned { step, phases }
    }

    #[inline(always)]
    fn row(&self, phase: usize, y: usize) -> (&[f32], &[f32]) {
        let (stride, values, valid) = &self.phases[phase];
        let range = y * stride..(y + 1) * stride;
        (&values[range.clone()], &valid[range])
    }
}

/// The sampling step of a window of radius `r`, pixels.
fn step_of(r: i64) -> usize {
    (r / SUBSAMPLE_DIVISOR).max(1) as usize
}

/// Lanes a window's row takes at most: `2·SUBSAMPLE_DIVISOR + 1` samples, rounded up.
const MAX_ROW_LANES: usize = (2 * SUBSAMPLE_DIVISOR as usize + 1).div_ceil(LANES) * LANES;

// Every radius' window row reaches at most SUBSAMPLE_DIVISOR samples from its centre (so it fits
// MAX_ROW_LANES and the padding), and its step divides the radius (so `count` covers it exactly).
const _: () = {
    let mut i = 0;
    while i < RADII.len() {
        let r = RADII[i];
        let step = if r / SUBSAMPLE_DIVISOR > 1 {
            r / SUBSAMPLE_DIVISOR
        } else {
            1
        };
        assert!(r % step == 0 && r / step <= SUBSAMPLE_DIVISOR);
        i += 1;
    }
};

/// The robust local fitter over one inverse-depth map.
pub(crate) struct LocalFitter<'a> {
    w: &'a Raster<f64>,
    /// `w` thinned at every step a window uses (1, 2, 4).
    thinned: Vec<Thinned>,
    camera: &'a Camera,
    /// Tukey cut-off, 1/m.
    c: f64,
    noise: NoiseScale,
}

impl<'a> LocalFitter<'a> {
    pub(crate) fn new(w: &'a Raster<f64>, camera: &'a Camera, noise: NoiseScale) -> Self {
        let mut steps: Vec<usize> = RADII.iter().map(|&r| step_of(r)).collect();
        steps.dedup();
        LocalFitter {
            w,
            thinned: steps
                .into_iter()
                .map(|step| Thinned::new(w, step))
                .collect(),
            camera,
            c: TUKEY_C * noise.sigma,
            noise,
        }
    }

    /// The window of radius `r` (thinned) around `(x0, y0)`, its rows clipped to the image;
    /// `None` when no row is inside.
    #[inline(always)]
    fn window(&self, x0: usize, y0: usize, r: i64) -> Option<Window<'_>> {
        let step = step_of(r);
        let thinned = self.thinned.iter().find(|t| t.step == step)?;
        let (step, height) = (step as i64, self.w.height() as i64);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = ((r - y0).max(0) + step - 1) / step;
        let bottom = ((height - 1).min(y0 + r) - (y0 - r)).div_euclid(step);
        if bottom < top {
            return None;
        }
        // Column x0 − r is sample (x0 − r − phase) / step of its phase's copy (negative ones
        // are in the padding).
        let left = x0 - r;
        let phase = left.rem_euclid(step);
        let start = THINNED_PAD as i64 + (left - phase) / step;
        Some(Window {
            thinned,
            phase: phase as usize,
            start: usize::try_from(start).ok()?,
            count: (2 * r / step + 1) as usize,
            y_start: (y0 - r + top * step) as usize,
            dv0: (top * step - r) as f64,
            rows: (bottom - top + 1) as usize,
        })
    }

    /// Tukey-weighted sums of the radius-`r` window's samples against `plane` (every valid
    /// sample weighted 1 without one); with `MOMENTS` false only the total weight is summed.
    /// Branch-free over [`LANES`] samples at a time so that the compiler vectorises it: this is
    /// where the scene mesh spends most of its time.
    ///
    /// The sums run in `f32` (eight lanes to a vector instead of four; the grid mesh's normals
    /// took 1.8× less time, docs/reconstruction-eval.md, stop 34) on inverse depths taken about
    /// a reference (the plane's at the centre, else the centre's own), so that what is summed is
    /// the small residual shape of the window rather than its large common offset; the offset's
    /// share of the `w` sums is added back in `f64`. The samples themselves are already `f32`
    /// ([`Thinned`]). Beyond about 10³⁵ m of depth the inverse of the Tukey scale leaves `f32`;
    /// every weight is then 0, no plane fits, and the mesh keeps its triangle normals there.
    #[inline(always)]
    fn window_sums<const MOMENTS: bool>(
        &self,
        x0: usize,
        y0: usize,
        r: i64,
        plane: Option<&LocalPlane>,
    ) -> WindowSums {
        // Without a plane, a zero plane and a zero scale give every residual the weight 1.
        let plane_given = plane.is_some();
        let (plane, inv_c) = match plane {
            Some(p) => (*p, 1.0 / self.c),
            None => (LocalPlane::default(), 0.0),
        };
        let Some(window) = self.window(x0, y0, r) else {
            return WindowSums::default();
        };
        let step = window.thinned.step as f32;
        // 1 for the window's own columns, 0 for those that only fill the last lane; and each
        // column's offset from the centre.
        let mut in_window = [0.0f32; MAX_ROW_LANES];
        in_window[..window.count].fill(1.0);
        let du_of: [f32; MAX_ROW_LANES] = std::array::from_fn(|i| i as f32 * step - r as f32);
        let reference = if plane_given {
            plane.g
        } else {
            Some(*self.w.get(x0, y0))
                .filter(|c| c.is_finite())
                .unwrap_or(0.0)
        };
        let (a, b, g) = (plane.a as f32, plane.b as f32, (plane.g - reference) as f32);
        let inv_c = inv_c as f32;
        let reference32 = reference as f32;
        let mut acc = [[0.0f32; LANES]; 9];
        for (y, dv) in window.rows() {
            let dv = dv as f32;
            let row_offset = b * dv + g;
            let (values, valid) = window.row(y);
            for (((values, valid), du), mask) in values
                .chunks_exact(LANES)
                .zip(valid.chunks_exact(LANES))
                .zip(du_of.chunks_exact(LANES))
                .zip(in_window.chunks_exact(LANES))
            {
                for l in 0..LANES {
                    let du = du[l];
                    let w = values[l] - reference32;
                    let t = (w - (a * du + row_offset)) * inv_c;
                    let s = (1.0 - t * t).max(0.0);
                    let k = s * s * valid[l] * mask[l];
                    acc[0][l] += k;
                    if MOMENTS {
                        let (ku, kv) = (k * du, k * dv);
                        acc[1][l] += ku;
                        acc[2][l] += kv;
                        acc[3][l] += ku * du;
                        acc[4][l] += ku * dv;
                        acc[5][l] += kv * dv;
                        acc[6][l] += k * w;
                        acc[7][l] += ku * w;
                        acc[8][l] += kv * w;
                    }
                }
            }
        }
        let [weight, du, dv, du_du, du_dv, dv_dv, w, du_w, dv_w] =
            acc.map(|l| l.iter().map(|&x| x as f64).sum::<f64>());
        let reference = reference32 as f64;
        WindowSums {
            weight,
            du,
            dv,
            du_du,
            du_dv,
            dv_dv,
            w: w + reference * weight,
            du_w: du_w + reference * du,
            dv_w: dv_w + reference * dv,
        }
    }

    /// Total Tukey weight of a plane's residuals in the radius-`r` window.
    fn support(&self, x0: usize, y0: usize, r: i64, plane: &LocalPlane) -> f64 {
        weight_sums(self, x0, y0, r, Some(plane)).weight
    }

    /// One reweighted least-squares step (every sample weighted 1 without a `plane`); `None` when
    /// too little support (below `min_weight`) or degenerate. Returns the new plane and the
    /// inverse of the weighted normal matrix (for its covariance).
    fn refit(
        &self,
        x0: usize,
        y0: usize,
        r: i64,
        plane: Option<&LocalPlane>,
        min_weight: f64,
    ) -> Option<(LocalPlane, DMat3)> {
        let s = moment_sums(self, x0, y0, r, plane);
        if s.weight < min_weight {
            return None;
        }
        let m = DMat3::from_cols(
            DVec3::new(s.du_du, s.du_dv, s.du),
            DVec3::new(s.du_dv, s.dv_dv, s.dv),
            DVec3::new(s.du, s.dv, s.weight),
        );
        // Relative conditioning check: a window whose inliers lie on a line cannot fix a plane.
        let det = m.determinant();
        let scale = m.x_axis.x * m.y_axis.y * m.z_axis.z;
        if !(det.is_finite() && scale > 0.0 && det > 1e-9 * scale) {
            return None;
        }
        let inv = m.inverse();
        let theta = inv * DVec3::new(s.du_w, s.dv_w, s.w);
        let plane = LocalPlane {
            a: theta.x,
            b: theta.y,
            g: theta.z,
        };
        (theta.is_finite()).then_some((plane, inv))
    }

    /// Standard error of the normal's direction (radians) for a fit over the radius-`r` window
    /// with parameter covariance `σ_w² · inv`, inflated for correlated samples: samples closer
    /// than the noise's correlation length share their error, so a window holds only about
    /// `(step / correlation)²` as many independent ones.
    fn normal_error(&self, plane: &LocalPlane, inv: &DMat3, r: i64, u0: f64, v0: f64) -> f64 {
        let step = step_of(r) as f64;
        let sigma = self.noise.sigma * (self.noise.correlation_px / step).max(1.0);
        let camera = self.camera;
        let (fx, fy) = (camera.fx as f64, camera.fy as f64);
        let (cx, cy) = (camera.cx as f64, camera.cy as f64);
        let n = unnormalised_normal(plane, camera, u0, v0);
        let len2 = n.length_squared();
        if len2.is_nan() || len2 <= 0.0 {
            return f64::INFINITY;
        }
        // d n / d (a, b, g), columns.
        let jac = DMat3::from_cols(
            DVec3::new(-fx, 0.0, cx - u0),
            DVec3::new(0.0, fy, cy - v0),
            DVec3::new(0.0, 0.0, 1.0),
        );
        let cov = jac * (*inv * sigma * sigma) * jac.transpose();
        let unit = n / len2.sqrt();
        let trace = cov.x_axis.x + cov.y_axis.y + cov.z_axis.z;
        let along = unit.dot(cov * unit);
        ((trace - along).max(0.0) / len2).sqrt()
    }

    /// The robust normal at pixel `(x0, y0)` (which must have depth), starting from the mesh's
    /// own normal `start` there when it has one. `None` when no plane fits.
    pub(crate) fn normal_at(&self, x0: usize, y0: usize, start: Option<Vec3>) -> Option<Vec3> {
        let w0 = *self.w.get(x0, y0);
        if !w0.is_finite() {
            return None;
        }
        let (u0, v0) = (x0 as f64 + 0.5, y0 as f64 + 0.5);
        // Candidate starts: constant inverse depth through the median of the 3×3 (one outlier
        // pixel cannot anchor it: right under heavy noise), the plain least-squares plane of the
        // 3×3 (right on clean depth away from edges), and the plane of the mesh's triangles
        // (right on clean depth at an edge, where the triangles are cut). The one with the most
        // support in the first window wins.
        let (width, height) = (self.w.width(), self.w.height());
        let mut near = [0.0f64; 9];
        let mut count = 0;
        for y in y0.saturating_sub(1)..=(y0 + 1).min(height - 1) {
            for &w in &self.w.row(y)[x0.saturating_sub(1)..=(x0 + 1).min(width - 1)] {
                if w.is_finite() {
                    near[count] = w;
                    count += 1;
                }
            }
        }
        // The centre is among them, so the 3×3 is never empty.
        let near = &mut near[..count];
        near.sort_by(f64::total_cmp);
        let flat = LocalPlane {
            a: 0.0,
            b: 0.0,
            g: near[count / 2],
        };
        let candidates = [
            Some(flat),
            self.refit(x0, y0, 1, None, 3.0).map(|(p, _)| p),
            start.and_then(|n| plane_from_normal(n.as_dvec3(), w0, self.camera, u0, v0)),
        ];
        let r0 = RADII[0];
        let mut plane = flat;
        let mut best = f64::NEG_INFINITY;
        for p in candidates.into_iter().flatten() {
            let support = self.support(x0, y0, r0, &p);
            if support > best {
                (plane, best) = (p, support);
            }
        }
        let mut fitted = None;
        'radii: for (k, &r) in RADII.iter().enumerate() {
            let rounds = if k == 0 { FIRST_RADIUS_ROUNDS } else { 1 };
            for _ in 0..rounds {
                match self.refit(x0, y0, r, Some(&plane), MIN_WEIGHT) {
                    Some((p, inv)) => {
                        plane = p;
                        fitted = Some(inv);
                    }
                    None => break 'radii,
                }
            }
            if let Some(inv) = &fitted {
                if self.normal_error(&plane, inv, r, u0, v0) < TARGET_NORMAL_ERROR_DEG.to_radians()
                {
                    break;
                }
            }
        }
        fitted?;
        normal_of(&plane, self.camera, u0, v0).map(|n| n.as_vec3())
    }
}

/// Robust normals at the given pixels of a depth map (see the module docs); `start` holds the
/// mesh's own normal for each (or `None`). Entries are `None` where no plane fits (isolated
/// samples), or all are when the noise cannot be estimated (too few valid pixels).
pub(crate) fn fitted_normals(
    depth: &Raster<f32>,
    camera: &Camera,
    pixels: &[(usize, usize)],
    start: &[Option<Vec3>],
) -> Vec<Option<Vec3>> {
    let w = inverse_depth(depth);
    let Some(noise) = correlated_noise(&w) else {
        return vec![None; pixels.len()];
    };
    let fitter = LocalFitter::new(&w, camera, noise);
    pixels
        .par_iter()
        .zip(start.par_iter())
        .map(|(&(x, y), s)| fitter.normal_at(x, y, *s))
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Depth of the plane `n · p = d` along the ray of pixel `(x, y)`.
    pub(crate) fn plane_depth(c: &Camera, n: Vec3, d: f32, x: usize, y: usize) -> f32 {
        let dir = c.unproject(x as f32 + 0.5, y as f32 + 0.5, 1.0).unwrap();
        d / n.dot(dir)
    }

    /// The window sums, written plainly: every `step`-th pixel of the window that lies in the
    /// image and has depth (held in f32, as the fitter does), Tukey-weighted against `plane`
    /// (or weight 1).
    fn plain_window_sums(
        fitter: &LocalFitter,
        x0: usize,
        y0: usize,
        r: i64,
        plane: Option<&LocalPlane>,
    ) -> [f64; 9] {
        let step = step_of(r) as i64;
        let mut sums = [0.0; 9];
        for dv in (-r..=r).step_by(step as usize) {
            for du in (-r..=r).step_by(step as usize) {
                let (x, y) = (x0 as i64 + du, y0 as i64 + dv);
                if x < 0 || y < 0 || x >= fitter.w.width() as i64 || y >= fitter.w.height() as i64 {
                    continue;
                }
                let w = *fitter.w.get(x as usize, y as usize) as f32 as f64;
                if !w.is_finite() {
                    continue;
                }
                let (du, dv) = (du as f64, dv as f64);
                let k = plane.map_or(1.0, |p| {
                    crate::robust::tukey(w - (p.a * du + p.b * dv + p.g), fitter.c)
                });
                let terms = [1.0, du, dv, du * du, du * dv, dv * dv, w, du * w, dv * w];
                for (s, t) in sums.iter_mut().zip(terms) {
                    *s += k * t;
                }
            }
        }
        sums
    }

    #[test]
    fn window_sums_match_the_plain_sums_at_edges_corners_and_holes() {
        // Every radius (and the 3×3), centres at corners, edges and inside, on an odd-sized map
        // with random holes; both the dispatched (AVX2 where present) and the baseline build.
        let (width, height) = (77, 53);
        let c = Camera::new(60.0, 60.0, 38.0, 26.0, width as u32, height as u32).unwrap();
        let mut rng = crate::mesh::surfaces::XorShift(7);
        let depth = Raster::from_fn(width, height, |_, _| {
            let u = gaussian(&mut rng);
            if u > 1.2 {
                f32::NAN
            } else {
                2.0 + 0.05 * u
            }
        });
        let w = inverse_depth(&depth);
        let noise = correlated_noise(&w).unwrap();
        let fitter = LocalFitter::new(&w, &c, noise);
        let plane = LocalPlane {
            a: 0.001,
            b: -0.002,
            g: 0.5,
        };
        let centres = [
            (0, 0),
            (76, 52),
            (0, 52),
            (76, 0),
            (38, 26),
            (3, 40),
            (70, 5),
            (31, 1),
        ];
        for r in std::iter::once(1).chain(RADII) {
            for &(x, y) in &centres {
                for p in [None, Some(&plane)] {
                    let want = plain_window_sums(&fitter, x, y, r, p);
                    for got in [
                        moment_sums(&fitter, x, y, r, p),
                        fitter.window_sums::<true>(x, y, r, p),
                    ] {
                        let got = [
                            got.weight, got.du, got.dv, got.du_du, got.du_dv, got.dv_dv, got.w,
                            got.du_w, got.dv_w,
                        ];
                        // Sums in f32: each within 10⁻⁵ of the size of its terms (weight n,
                        // offsets up to r, inverse depths about 0.5 here). One sample too many
                        // or too few, or misplaced by a column, is off by 1/n of it or more.
                        let n = 1.0 + want[0];
                        let r = r as f64;
                        let size = [
                            n,
                            n * r,
                            n * r,
                            n * r * r,
                            n * r * r,
                            n * r * r,
                            n,
                            n * r,
                            n * r,
                        ];
                        for ((g, w), size) in got.iter().zip(want).zip(size) {
                            assert!(
                                (g - w).abs() <= 1e-5 * size,
                                "r {r} at ({x}, {y}), plane {p:?}: {got:?} against {want:?}"
                            );
                        }
                    }
                    let weight = p.map_or(want[0], |p| fitter.support(x, y, r, p));
                    assert!((weight - want[0]).abs() <= 1e-5 * (1.0 + want[0]));
                }
            }
        }
    }

    #[test]
    fn normal_of_an_exact_plane_is_exact_off_centre() {
        let c = Camera::new(300.0, 320.0, 70.0, 40.0, 120, 90).unwrap();
        let n = Vec3::new(0.3, 0.8, 0.4).normalize();
        let depth = Raster::from_fn(120, 90, |x, y| plane_depth(&c, n, -2.0, x, y));
        let w = inverse_depth(&depth);
        let noise = correlated_noise(&w).unwrap();
        let fitter = LocalFitter::new(&w, &c, noise);
        for (x, y) in [(0, 0), (60, 45), (119, 89), (10, 80)] {
            let got = fitter.normal_at(x, y, None).unwrap();
            assert!(got.angle_between(n).to_degrees() < 0.01, "{x},{y}: {got}");
        }
    }

    #[test]
    fn noise_estimate_recovers_white_disparity_noise() {
        // A slanted plane with Gaussian noise of known σ added to its inverse depth.
        let c = Camera::from_focal(400.0, 200, 150).unwrap();
        let n = Vec3::new(0.0, 0.6, 0.8);
        let mut rng = crate::mesh::surfaces::XorShift(7);
        let sigma = 0.004;
        let depth = Raster::from_fn(200, 150, |x, y| {
            let z = plane_depth(&c, n, -2.0, x, y);
            1.0 / (1.0 / z + sigma * gaussian(&mut rng))
        });
        let est = correlated_noise(&inverse_depth(&depth)).unwrap();
        assert!(
            (est.sigma as f32 / sigma - 1.0).abs() < 0.1,
            "estimated {est:?}, true {sigma}"
        );
        assert_eq!(est.correlation_px, 1.0, "white noise is uncorrelated");
    }

    /// White noise averaged over a `(2·radius + 1)²` box, rescaled to standard deviation `sigma`:
    /// errors correlated over about `2·radius + 1` pixels, like a matcher's after aggregation.
    pub(crate) fn correlated_noise_field(
        width: usize,
        height: usize,
        radius: usize,
        sigma: f32,
        seed: u64,
    ) -> Raster<f32> {
        let mut rng = crate::mesh::surfaces::XorShift(seed);
        let (pw, ph) = (width + 2 * radius, height + 2 * radius);
        let white: Vec<f32> = (0..pw * ph).map(|_| gaussian(&mut rng)).collect();
        let side = (2 * radius + 1) as f32;
        Raster::from_fn(width, height, |x, y| {
            let mut sum = 0.0;
            for dy in 0..=2 * radius {
                for dx in 0..=2 * radius {
                    sum += white[(y + dy) * pw + x + dx];
                }
            }
            // The mean of side² unit deviates has standard deviation 1/side.
            sum / (side * side) * side * sigma
        })
    }

    #[test]
    fn noise_estimate_sees_correlated_noise_that_short_differences_miss() {
        // Errors correlated over 9 px: second differences at 1–3 px cancel most of them.
        let c = Camera::from_focal(400.0, 240, 180).unwrap();
        let n = Vec3::new(0.0, 0.6, 0.8);
        let sigma = 0.004;
        let noise = correlated_noise_field(240, 180, 4, sigma, 3);
        let depth = Raster::from_fn(240, 180, |x, y| {
            1.0 / (1.0 / plane_depth(&c, n, -2.0, x, y) + *noise.get(x, y))
        });
        let w = inverse_depth(&depth);
        let short = inverse_depth_noise(&w, 3).unwrap() as f32;
        assert!(short < 0.5 * sigma, "spacing 3 sees {short} of {sigma}");
        let est = correlated_noise(&w).unwrap();
        assert!(
            (est.sigma as f32 / sigma - 1.0).abs() < 0.25,
            "estimated {est:?}, true {sigma}"
        );
        assert!(
            (4.0..=16.0).contains(&est.correlation_px),
            "correlation {est:?}"
        );
    }

    #[test]
    fn noise_ladder_stops_where_curvature_takes_over() {
        // An exact sphere: its second differences grow as the spacing squared; none is noise.
        let c = Camera::from_focal(400.0, 200, 150).unwrap();
        let depth = Raster::from_fn(200, 150, |x, y| {
            let r = c.unproject(x as f32 + 0.5, y as f32 + 0.5, 1.0).unwrap();
            let (u, v) = (r.x, r.y);
            // Depth of a sphere of radius 1 centred 3 m ahead, along a ray with z = −1.
            let a = 1.0 + u * u + v * v;
            let disc = 9.0 - a * 8.0;
            if disc < 0.0 {
                f32::NAN
            } else {
                (3.0 - disc.sqrt()) / a
            }
        });
        let w = inverse_depth(&depth);
        let est = correlated_noise(&w).unwrap();
        let at_16 = inverse_depth_noise(&w, 16).unwrap();
        assert!(est.sigma < 0.25 * at_16, "{est:?} against {at_16} at 16 px");
    }

    /// Standard normal deviate (Box–Muller).
    pub(crate) fn gaussian(rng: &mut crate::mesh::surfaces::XorShift) -> f32 {
        let u1 = rng.unit().max(1e-7);
        let u2 = rng.unit();
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }
}
