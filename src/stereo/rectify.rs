//! Getting a pair into the rectified form the matcher needs.
//!
//! - **Near-stereo input** (thesis §4.2.2, phone pairs taken by hand): the right view may sit a few
//!   pixels higher or lower and be turned slightly. [`estimate_misalignment`] finds the vertical
//!   offset (±8 px) and rotation (≤ 1°) that make rows correspond best, scoring each candidate by how
//!   well pixels find a horizontal census match; [`apply_misalignment`] resamples the right view.
//! - **Calibrated input**: [`rectification_from_calibration`] builds the two homographies of
//!   Fusiello, Trucco and Verri (2000) from intrinsics and the relative pose, and
//!   [`rectify_images`] resamples both views.

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::census::census_transform;
use super::pyramid::reduce;
use crate::camera::StereoCalibration;
use crate::error::{Error, Result};
use crate::image::{Image, ImageView, Raster};

/// Largest vertical offset searched, pixels.
pub const MAX_VERTICAL_OFFSET: f32 = 8.0;
/// Largest rotation searched, degrees.
pub const MAX_ROTATION_DEG: f32 = 1.0;

/// How the right view is displaced relative to the left: its content at `(x, y)` of a rectified
/// right view is found at `c + R(angle)·((x, y) − c) + (0, dy)`, `c` the image centre.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Misalignment {
    /// Vertical offset, pixels (positive: the right view's content sits lower).
    pub dy: f32,
    /// Rotation, degrees (positive turns x towards y, i.e. clockwise on screen).
    pub angle_deg: f32,
}

/// Samples `image` where a rectified right view's pixels come from (bilinear, borders replicate).
pub fn apply_misalignment(image: &Raster<u8>, m: &Misalignment) -> Raster<u8> {
    if m.dy == 0.0 && m.angle_deg == 0.0 {
        return image.clone();
    }
    let (w, h) = (image.width(), image.height());
    let mut out = vec![0u8; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        warp_row(image, m, y as f32, row);
    });
    Raster::from_vec(w, h, out)
}

fn warp_row(image: &Raster<u8>, m: &Misalignment, y: f32, row: &mut [u8]) {
    let (w, h) = (image.width(), image.height());
    let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
    let (s, c) = m.angle_deg.to_radians().sin_cos();
    for (x, out) in row.iter_mut().enumerate() {
        let (u, v) = (x as f32 - cx, y - cy);
        let sx = cx + c * u - s * v;
        let sy = cy + s * u + c * v + m.dy;
        *out = bilinear(image, sx, sy);
    }
}

fn bilinear(image: &Raster<u8>, x: f32, y: f32) -> u8 {
    let (w, h) = (image.width() as isize, image.height() as isize);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |xi: isize, yi: isize| {
        *image.get(xi.clamp(0, w - 1) as usize, yi.clamp(0, h - 1) as usize) as f32
    };
    let (xi, yi) = (x0 as isize, y0 as isize);
    let top = at(xi, yi) * (1.0 - fx) + at(xi + 1, yi) * fx;
    let bottom = at(xi, yi + 1) * (1.0 - fx) + at(xi + 1, yi + 1) * fx;
    (top * (1.0 - fy) + bottom * fy + 0.5).clamp(0.0, 255.0) as u8
}

/// Mean best horizontal census cost of sampled left pixels against the right view resampled with
/// `m`: low when rows correspond.
fn alignment_cost(
    left_census: &[u64],
    right: &Raster<u8>,
    m: &Misalignment,
    max_d: usize,
    row_step: usize,
) -> f64 {
    let (w, h) = (right.width(), right.height());
    let r = 2usize;
    let rows: Vec<usize> = (r..h.saturating_sub(r)).step_by(row_step).collect();
    let total: u64 = rows
        .par_iter()
        .map(|&y| {
            // Resample the 5 rows around y, then census-transform the middle one.
            let mut band = vec![0u8; w * (2 * r + 1)];
            for (j, dst) in band.chunks_mut(w).enumerate() {
                warp_row(right, m, (y + j - r) as f32, dst);
            }
            let band = Raster::from_vec(w, 2 * r + 1, band);
            let census = census_transform(&band, r, r);
            let rc = &census[r * w..(r + 1) * w];
            let lc = &left_census[y * w..(y + 1) * w];
            let mut sum = 0u64;
            for x in max_d..w {
                let best = (0..=max_d)
                    .map(|d| (lc[x] ^ rc[x - d]).count_ones())
                    .min()
                    .unwrap_or(0);
                sum += best as u64;
            }
            sum
        })
        .sum();
    let count = rows.len() * w.saturating_sub(max_d);
    if count == 0 {
        0.0
    } else {
        total as f64 / count as f64
    }
}

/// Estimates the right view's vertical offset (within ±[`MAX_VERTICAL_OFFSET`]) and rotation
/// (within ±[`MAX_ROTATION_DEG`]) relative to the left, for disparities up to `max_disparity`.
///
/// A coarse search at reduced size (width ≤ 400) over the whole range, one parameter at a time,
/// then a finer search at full size around it. Images too small to say anything give zero.
pub fn estimate_misalignment(
    left: &Raster<u8>,
    right: &Raster<u8>,
    max_disparity: usize,
) -> Misalignment {
    let (w, h) = (left.width(), left.height());
    if w < 16 || h < 16 || max_disparity + 8 >= w {
        return Misalignment::default();
    }
    // Pyramid down to at most 400 px wide.
    let mut levels = vec![(left.clone(), right.clone())];
    while let Some((l, r)) = levels.last() {
        if l.width() <= 400 || l.height() <= 64 {
            break;
        }
        let next = (reduce(l), reduce(r));
        levels.push(next);
    }
    let mut best = Misalignment::default();
    let n = levels.len();
    for (i, (l, r)) in levels.iter().enumerate().rev() {
        let scale = (1usize << i) as f32;
        let census = census_transform(l, 2, 2);
        let max_d = (max_disparity as f32 / scale).ceil() as usize + 1;
        let max_d = max_d.min(l.width() / 2);
        let row_step = (l.height() / 60).max(2);
        let eval = |m: &Misalignment| {
            let scaled = Misalignment {
                dy: m.dy / scale,
                angle_deg: m.angle_deg,
            };
            alignment_cost(&census, r, &scaled, max_d, row_step)
        };
        // Coarsest level: the whole range; finer levels: around the current estimate.
        let (dy_range, dy_step, a_range, a_step) = if i == n - 1 {
            (MAX_VERTICAL_OFFSET, 0.5 * scale, MAX_ROTATION_DEG, 0.25)
        } else {
            (1.5 * scale, 0.25 * scale, 0.25, 0.0625)
        };
        let dy_centre = best.dy;
        let a_centre = best.angle_deg;
        for _round in 0..2 {
            best.dy = search(dy_centre, dy_range, dy_step, MAX_VERTICAL_OFFSET, |dy| {
                eval(&Misalignment { dy, ..best })
            });
            best.angle_deg = search(a_centre, a_range, a_step, MAX_ROTATION_DEG, |a| {
                eval(&Misalignment {
                    angle_deg: a,
                    ..best
                })
            });
        }
    }
    best
}

/// The value in `centre ± range` (step `step`, clamped to `±limit`) with the lowest cost.
fn search(centre: f32, range: f32, step: f32, limit: f32, cost: impl Fn(f32) -> f64) -> f32 {
    let count = (range / step).round() as i32;
    let mut best = (f64::INFINITY, centre);
    for i in -count..=count {
        let v = (centre + i as f32 * step).clamp(-limit, limit);
        let c = cost(v);
        // Prefer the smaller correction on ties.
        if c < best.0 - 1e-9 || (c <= best.0 + 1e-9 && v.abs() < best.1.abs()) {
            best = (c, v);
        }
    }
    best.1
}

/// Intrinsics and relative pose of an unrectified pair (OpenCV's `stereoCalibrate` convention:
/// pixel coordinates x right, y down; a point `X` in the left camera's frame is `R·X + T` in the
/// right camera's, so a right camera `B` metres to the right has `T ≈ (−B, 0, 0)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPair {
    /// Left intrinsics `[f 0 cx; 0 f cy; 0 0 1]` (column-major glam matrix).
    pub k_left: DMat3,
    /// Right intrinsics.
    pub k_right: DMat3,
    /// Rotation from the left camera's frame to the right camera's.
    pub r: DMat3,
    /// Translation from the left camera's frame to the right camera's, metres.
    pub t: DVec3,
}

/// Homographies taking original pixel coordinates to rectified ones, and the rectified calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rectification {
    /// Left original → rectified pixel (homogeneous).
    pub h_left: DMat3,
    /// Right original → rectified pixel.
    pub h_right: DMat3,
    /// The rectified pair's calibration (`doffs` 0: both views share the new intrinsics).
    pub calibration: StereoCalibration,
}

/// Fusiello–Trucco–Verri rectification: both cameras are turned to a common orientation whose x
/// axis is the baseline, and given the mean of the two intrinsics.
///
/// # Errors
/// `InvalidArgument` for non-finite values, a zero baseline, a baseline along the optical axis, or
/// singular intrinsics.
pub fn rectification_from_calibration(
    pair: &CameraPair,
    width: u32,
    height: u32,
) -> Result<Rectification> {
    let finite = [pair.k_left, pair.k_right, pair.r]
        .iter()
        .all(|m| m.to_cols_array().iter().all(|v| v.is_finite()))
        && pair.t.is_finite();
    if !finite {
        return Err(Error::invalid(
            "rectification: calibration has a non-finite value",
        ));
    }
    for (name, k) in [("left", pair.k_left), ("right", pair.k_right)] {
        if k.determinant().abs() < 1e-12 || k.x_axis.x <= 0.0 || k.y_axis.y <= 0.0 {
            return Err(Error::invalid(format!(
                "rectification: {name} intrinsics are singular or have a non-positive focal length"
            )));
        }
    }
    // Camera centres in the left frame: C_l = 0, C_r = −Rᵀ·T.
    let centre_right = -(pair.r.transpose() * pair.t);
    let baseline = centre_right.length();
    if baseline < 1e-12 {
        return Err(Error::invalid("rectification: the baseline is zero"));
    }
    let x_axis = centre_right / baseline;
    let y_axis = DVec3::Z.cross(x_axis);
    if y_axis.length() < 1e-6 {
        return Err(Error::invalid(
            "rectification: the baseline is along the optical axis",
        ));
    }
    let y_axis = y_axis.normalize();
    let z_axis = x_axis.cross(y_axis);
    // Rows of the new rotation are the new axes.
    let r_new = DMat3::from_cols(x_axis, y_axis, z_axis).transpose();
    let mut k_new = (pair.k_left + pair.k_right) * 0.5;
    k_new.y_axis.x = 0.0; // no skew
    let h_left = k_new * r_new * pair.k_left.inverse();
    let h_right = k_new * r_new * pair.r.transpose() * pair.k_right.inverse();
    let focal = k_new.x_axis.x;
    let calibration = StereoCalibration {
        focal_px: focal,
        cx: k_new.z_axis.x,
        cy: k_new.z_axis.y,
        baseline_m: baseline,
        doffs: 0.0,
        max_disparity: None,
    };
    calibration.validate()?;
    let _ = (width, height);
    Ok(Rectification {
        h_left,
        h_right,
        calibration,
    })
}

/// Resamples an image through a homography (output pixel `p` takes input `H⁻¹·p`, bilinear in
/// linear light; outside the input is black). Output is RGB8 sRGB of the same size.
///
/// # Errors
/// `InvalidArgument` for a singular homography.
pub fn warp_homography(image: &ImageView, h: &DMat3) -> Result<Image> {
    if h.determinant().abs() < 1e-15 || !h.determinant().is_finite() {
        return Err(Error::invalid("warp: the homography is singular"));
    }
    let inv = h.inverse();
    let src = image.to_linear_rgb();
    let (w, hgt) = (src.width(), src.height());
    let out = Raster::from_fn(w, hgt, |x, y| {
        let p = inv * DVec3::new(x as f64 + 0.5, y as f64 + 0.5, 1.0);
        if p.z.abs() < 1e-12 {
            return [0.0; 3];
        }
        let (sx, sy) = (p.x / p.z - 0.5, p.y / p.z - 0.5);
        if sx < -0.5 || sy < -0.5 || sx > w as f64 - 0.5 || sy > hgt as f64 - 0.5 {
            return [0.0; 3];
        }
        let (x0, y0) = (sx.floor(), sy.floor());
        let (fx, fy) = ((sx - x0) as f32, (sy - y0) as f32);
        let at = |xi: f64, yi: f64| {
            *src.get(
                (xi.max(0.0) as usize).min(w - 1),
                (yi.max(0.0) as usize).min(hgt - 1),
            )
        };
        let (a, b, c, d) = (
            at(x0, y0),
            at(x0 + 1.0, y0),
            at(x0, y0 + 1.0),
            at(x0 + 1.0, y0 + 1.0),
        );
        let mut v = [0.0; 3];
        for i in 0..3 {
            v[i] =
                (a[i] * (1.0 - fx) + b[i] * fx) * (1.0 - fy) + (c[i] * (1.0 - fx) + d[i] * fx) * fy;
        }
        v
    });
    Ok(Image::from_linear_rgb(&out))
}

/// Rectifies an unrectified pair: both views resampled, plus the calibration of the result.
///
/// # Errors
/// `SizeMismatch` for views of different sizes; as [`rectification_from_calibration`].
pub fn rectify_images(
    left: &ImageView,
    right: &ImageView,
    pair: &CameraPair,
) -> Result<(Image, Image, StereoCalibration)> {
    if (left.width(), left.height()) != (right.width(), right.height()) {
        return Err(Error::SizeMismatch(format!(
            "rectification: left {}x{} and right {}x{} differ",
            left.width(),
            left.height(),
            right.width(),
            right.height()
        )));
    }
    let rect = rectification_from_calibration(pair, left.width(), left.height())?;
    Ok((
        warp_homography(left, &rect.h_left)?,
        warp_homography(right, &rect.h_right)?,
        rect.calibration,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stereo::tests::texture;

    #[test]
    fn recovers_a_vertical_offset_and_a_small_rotation() {
        let (w, h) = (320, 240);
        let left = Raster::from_fn(w, h, |x, y| texture(x as f32, y as f32));
        let truth = Misalignment {
            dy: 5.0,
            angle_deg: 0.6,
        };
        // The right view: content at disparity 6, displaced by `truth`. Build it by sampling the
        // texture where the rectified right pixel's content lies, inverting the model.
        let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
        let (s, c) = truth.angle_deg.to_radians().sin_cos();
        let right = Raster::from_fn(w, h, |x, y| {
            // Original right pixel (x, y) = c + R(θ)(q − c) + (0, dy) for rectified q: invert.
            let (u, v) = (x as f32 - cx, y as f32 - cy - truth.dy);
            let (qx, qy) = (cx + c * u + s * v, cy - s * u + c * v);
            texture(qx + 6.0, qy)
        });
        let est = estimate_misalignment(&left, &right, 16);
        assert!((est.dy - truth.dy).abs() <= 0.5, "{est:?}");
        assert!((est.angle_deg - truth.angle_deg).abs() <= 0.15, "{est:?}");
        // An aligned pair needs no correction.
        let aligned = Raster::from_fn(w, h, |x, y| texture(x as f32 + 6.0, y as f32));
        let est = estimate_misalignment(&left, &aligned, 16);
        assert!(
            est.dy.abs() <= 0.25 && est.angle_deg.abs() <= 0.07,
            "{est:?}"
        );
    }

    #[test]
    fn calibrated_rectification_aligns_rows_and_gives_true_disparity() {
        let k = DMat3::from_cols(
            DVec3::new(500.0, 0.0, 0.0),
            DVec3::new(0.0, 510.0, 0.0),
            DVec3::new(320.0, 240.0, 1.0),
        );
        let k2 = DMat3::from_cols(
            DVec3::new(505.0, 0.0, 0.0),
            DVec3::new(0.0, 505.0, 0.0),
            DVec3::new(330.0, 235.0, 1.0),
        );
        let r = DMat3::from_rotation_y(0.03)
            * DMat3::from_rotation_x(-0.02)
            * DMat3::from_rotation_z(0.01);
        let centre_right = DVec3::new(0.12, 0.004, -0.003);
        let pair = CameraPair {
            k_left: k,
            k_right: k2,
            r,
            t: -(r * centre_right),
        };
        let rect = rectification_from_calibration(&pair, 640, 480).unwrap();
        assert!((rect.calibration.baseline_m - centre_right.length()).abs() < 1e-9);
        let project = |h: &DMat3, kk: &DMat3, cam: DVec3| {
            let p = *h * (*kk * cam);
            (p.x / p.z, p.y / p.z)
        };
        for &(x, y, z) in &[
            (0.1, 0.2, 2.0),
            (-0.5, 0.1, 3.5),
            (0.3, -0.4, 1.2),
            (0.0, 0.0, 8.0),
        ] {
            let pl = DVec3::new(x, y, z);
            let pr = r * pl + pair.t;
            let (xl, yl) = project(&rect.h_left, &k, pl);
            let (xr, yr) = project(&rect.h_right, &k2, pr);
            assert!((yl - yr).abs() < 1e-6, "rows differ: {yl} vs {yr}");
            // Depth along the new optical axis from the disparity.
            let z_new = (rect.calibration.focal_px * rect.calibration.baseline_m) / (xl - xr);
            let r_new_z = {
                let xa = centre_right.normalize();
                let ya = DVec3::Z.cross(xa).normalize();
                xa.cross(ya)
            };
            assert!((z_new - pl.dot(r_new_z)).abs() < 1e-6 * z_new.abs().max(1.0));
        }
        let bad = CameraPair {
            t: DVec3::ZERO,
            ..pair
        };
        assert!(rectification_from_calibration(&bad, 640, 480).is_err());
        let nan = CameraPair {
            t: DVec3::new(f64::NAN, 0.0, 0.0),
            ..pair
        };
        assert!(rectification_from_calibration(&nan, 640, 480).is_err());
    }

    #[test]
    fn identity_warp_keeps_the_image() {
        let img = Image::from_bytes(
            6,
            4,
            crate::image::PixelFormat::Rgb8,
            (0..72).map(|i| (i * 3) as u8).collect(),
        )
        .unwrap();
        let out = warp_homography(&img.view(), &DMat3::IDENTITY).unwrap();
        assert_eq!(out.as_bytes(), img.as_bytes());
        assert!(warp_homography(&img.view(), &DMat3::ZERO).is_err());
    }
}
