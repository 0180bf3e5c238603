//! The light arriving at a point from every direction: an HDR cube map and its SH9 irradiance.
//!
//! Three sources:
//! - [`Environment::from_equirect`]: a host's HDR/EXR latitude-longitude map (the reference's
//!   layout: the centre column looks along −Z, +X at three quarters, the top row is +Y).
//! - [`Environment::from_photo`]: the photo re-projected through its depth onto a sphere around the
//!   insertion point. Each direction from the point is ray-marched through the depth map (see
//!   `march`): the first visible surface the ray meets is what the point sees there, with that
//!   pixel's colour (Lambertian surfaces look the same from the point as from the camera). This
//!   keeps occlusion right where forward-splatting the pixels does not: a table top 2 cm below
//!   the point fills the whole lower hemisphere from a handful of pixels, and hides the floor the
//!   camera sees in front of it. Pixels without depth (sky, far lamps) are infinitely far. LDR
//!   photos are expanded to HDR first (see [`inverse_tone_map`]). Directions the camera never saw
//!   (behind it, above it, behind objects) are filled in two steps: small holes by pull-push (the
//!   map averaged down a few pyramid levels counting only seen cells, not lights and their glare,
//!   which are never copied anywhere), and what is left from the
//!   seen directions at the same elevation above the horizon of gravity `up`
//!   ([`Environment::from_photo_with_up`]): a room goes on behind the camera much as it looks in
//!   front, floor below, walls at the horizon, ceiling above. An elevation band seen over less
//!   than 5 % of its solid angle (a lamp's fixture at the top of the frame) is no sample of its
//!   band: bands take the nearest band seen over more, and bright pixels (lights and their
//!   glare, as [`crate::light::detect_sources`] finds them) are never copied. When the lights
//!   were fitted ([`crate::light::estimate_lighting`]), the copy is relit: each unseen direction
//!   looks at a stand-in surface at the point, facing back along the direction (where the unseen
//!   surfaces are is not known; see `relight`), and takes its band's mean times that surface's
//!   irradiance under the fitted ambient and lights over the mean irradiance of the seen surfaces
//!   it copies (at most 4×). A ceiling copied from the tops of walls then gets the ambient light
//!   and the lamps below the point, not the ceiling lamp that lit the walls' tops. Lights
//!   (detected or fitted) are then drawn into the map as discs of their solid angle.
//! - [`Environment::from_cube`]: a cube map directly.
//!
//! SH projection robustness: every texel is made finite and non-negative (NaN → 0, negative → 0,
//! +inf → the clamp) and clamped to `max_radiance` (luminance-preserving) before projection, so a
//! 10⁶-bright sun pixel cannot swamp the ambient term — such a peak belongs to a directional
//! light, not to nine smooth coefficients. The optional Lanczos window (`sh_window`) damps bands 1
//! and 2 to reduce the ringing a small bright source causes (at the price of some blur). The cube
//! itself keeps values up to the largest half float (65504), as an RGBA16F texture can hold.

use glam::Vec3;
use rayon::prelude::*;

use super::filters::{check_photo_camera, check_same, check_size, luminance};
use super::model::{
    cube_direction, cube_texel, CubeLevel, CubeMap, Light, LightKind, Sh9, CUBE_FACES,
};
use super::prefilter::prefilter_ggx;
use super::sources::{bright_pixels, SourceOptions};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;

/// Largest value a texel keeps in the cube (the largest finite half float).
pub const HALF_MAX: f32 = 65504.0;

/// Options of the environment builders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvironmentOptions {
    /// Cube face edge, texels (4..=1024).
    pub face_size: u32,
    /// Texels brighter than this (luminance) are scaled down to it before SH projection (> 0).
    pub max_radiance: f32,
    /// Lanczos window strength on SH bands 1 and 2, in [0, 1] (0 = none).
    pub sh_window: f32,
    /// What a fully saturated LDR pixel is expanded to (≥ 1).
    pub ldr_peak: f32,
}

impl Default for EnvironmentOptions {
    fn default() -> Self {
        EnvironmentOptions {
            face_size: 64,
            max_radiance: 1000.0,
            sh_window: 0.0,
            ldr_peak: 8.0,
        }
    }
}

impl EnvironmentOptions {
    /// Checks ranges.
    ///
    /// # Errors
    /// `InvalidArgument` naming the option out of range.
    pub fn validate(&self) -> Result<()> {
        if !(4..=1024).contains(&self.face_size) {
            return Err(Error::invalid(format!(
                "environment face_size must be in 4..=1024, got {}",
                self.face_size
            )));
        }
        if !(self.max_radiance.is_finite() && self.max_radiance > 0.0) {
            return Err(Error::invalid(format!(
                "environment max_radiance must be finite and > 0, got {}",
                self.max_radiance
            )));
        }
        if !(0.0..=1.0).contains(&self.sh_window) {
            return Err(Error::invalid(format!(
                "environment sh_window must be in [0, 1], got {}",
                self.sh_window
            )));
        }
        if !(self.ldr_peak.is_finite() && self.ldr_peak >= 1.0) {
            return Err(Error::invalid(format!(
                "environment ldr_peak must be finite and >= 1, got {}",
                self.ldr_peak
            )));
        }
        Ok(())
    }
}

/// Where an environment came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EnvironmentSource {
    /// Re-projected from the photo.
    Photo,
    /// A host's or library's map.
    Map,
}

/// HDR radiance around a point, with its SH9 irradiance.
#[derive(Debug, Clone, PartialEq)]
pub struct Environment {
    /// Linear radiance, one level (see [`Environment::prefiltered`] for the glossy mips).
    pub cube: CubeMap,
    /// Irradiance in [`Sh9`]'s convention, projected from the clamped cube.
    pub sh9: Sh9,
    /// Fraction of directions (by solid angle) that the photo showed (1 for a map).
    pub seen_fraction: f32,
    /// Where it came from.
    pub source: EnvironmentSource,
}

/// Expands an LDR linear value (the photo's white = 1) to HDR: values up to 0.8 are kept, and
/// above that a quadratic rises to `peak` at 1.0 (continuous with slope 1 at 0.8), so only
/// near-saturated pixels — lamps, windows, highlights — are boosted. The LDR photo cannot tell how
/// much brighter a clipped lamp was; `peak` is that guess. Non-finite or negative input gives 0.
pub fn inverse_tone_map(c: [f32; 3], peak: f32) -> [f32; 3] {
    const KNEE: f32 = 0.8;
    c.map(|v| {
        let v = if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        };
        if v <= KNEE {
            v
        } else {
            let t = (v - KNEE) / (1.0 - KNEE);
            // v + k·t² reaches `peak` at t = 1.
            v + (peak - 1.0).max(0.0) * t * t
        }
    })
}

fn sanitize(c: [f32; 3], clamp: f32) -> [f32; 3] {
    c.map(|v| if v.is_nan() { 0.0 } else { v.clamp(0.0, clamp) })
}

/// Solid angle of the cube texel `(i, j)` of an `n × n` face.
fn texel_solid_angle(i: usize, j: usize, n: usize) -> f32 {
    let corner = |x: f64, y: f64| (x * y).atan2((x * x + y * y + 1.0).sqrt());
    let (x0, x1) = (
        2.0 * i as f64 / n as f64 - 1.0,
        2.0 * (i + 1) as f64 / n as f64 - 1.0,
    );
    let (y0, y1) = (
        2.0 * j as f64 / n as f64 - 1.0,
        2.0 * (j + 1) as f64 / n as f64 - 1.0,
    );
    (corner(x0, y0) - corner(x0, y1) - corner(x1, y0) + corner(x1, y1)) as f32
}

/// The unit direction of equirect position `(u, v)` ∈ [0, 1]² (the reference's layout).
pub fn equirect_direction(u: f32, v: f32) -> Vec3 {
    let phi = (u - 0.5) * 2.0 * std::f32::consts::PI;
    let theta = v * std::f32::consts::PI;
    Vec3::new(
        theta.sin() * phi.sin(),
        theta.cos(),
        -theta.sin() * phi.cos(),
    )
}

/// The equirect position of a unit direction; the inverse of [`equirect_direction`].
pub fn equirect_position(d: Vec3) -> (f32, f32) {
    let d = d.normalize_or(Vec3::NEG_Z);
    let theta = d.y.clamp(-1.0, 1.0).acos();
    let phi = d.x.atan2(-d.z);
    (
        (phi / (2.0 * std::f32::consts::PI) + 0.5).rem_euclid(1.0),
        theta / std::f32::consts::PI,
    )
}

/// Projects a cube level's radiance onto SH9 (clamped and optionally windowed, see the module).
pub fn sh9_from_cube(level: &CubeLevel, max_radiance: f32, window: f32) -> Sh9 {
    let n = level.size as usize;
    let mut proj = [[0.0f64; 3]; 9];
    for f in 0..CUBE_FACES {
        for j in 0..n {
            for i in 0..n {
                let d = cube_direction(f, (i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let mut c = sanitize(level.texels[f * n * n + j * n + i], f32::MAX);
                let y = luminance(c);
                if y > max_radiance {
                    c = c.map(|v| v * max_radiance / y);
                }
                let w = texel_solid_angle(i, j, n) as f64;
                let basis = [
                    0.282_095,
                    0.488_603 * d.y,
                    0.488_603 * d.z,
                    0.488_603 * d.x,
                    1.092_548 * d.x * d.y,
                    1.092_548 * d.y * d.z,
                    0.315_392 * (3.0 * d.z * d.z - 1.0),
                    1.092_548 * d.x * d.z,
                    0.546_274 * (d.x * d.x - d.y * d.y),
                ];
                for (p, b) in proj.iter_mut().zip(basis) {
                    for k in 0..3 {
                        p[k] += c[k] as f64 * b as f64 * w;
                    }
                }
            }
        }
    }
    let sinc = |x: f64| {
        if x == 0.0 {
            1.0
        } else {
            (std::f64::consts::PI * x).sin() / (std::f64::consts::PI * x)
        }
    };
    let band = [0usize, 1, 1, 1, 2, 2, 2, 2, 2];
    let mut radiance = [[0.0f32; 3]; 9];
    for i in 0..9 {
        let l = band[i] as f64;
        let factor = 1.0 - window as f64 * (1.0 - sinc(l / 3.0));
        radiance[i] = proj[i].map(|v| (v * factor) as f32);
    }
    Sh9::from_radiance_projection(radiance)
}

/// Resamples an equirect map into a cube level: texels covered by several map pixels average them
/// (weighted by solid angle, so small bright sources keep their energy); the others take the
/// nearest map pixel.
fn equirect_to_cube(map: &Raster<[f32; 3]>, n: usize) -> CubeLevel {
    let (w, h) = (map.width(), map.height());
    let mut sum = vec![[0.0f64; 3]; CUBE_FACES * n * n];
    let mut weight = vec![0.0f64; CUBE_FACES * n * n];
    for y in 0..h {
        let v = (y as f32 + 0.5) / h as f32;
        let area = (v * std::f32::consts::PI).sin().max(1e-6) as f64;
        for x in 0..w {
            let d = equirect_direction((x as f32 + 0.5) / w as f32, v);
            let (f, s, t) = cube_texel(d);
            let idx = f * n * n
                + ((t * n as f32) as usize).min(n - 1) * n
                + ((s * n as f32) as usize).min(n - 1);
            let c = map.get(x, y);
            for k in 0..3 {
                sum[idx][k] += c[k] as f64 * area;
            }
            weight[idx] += area;
        }
    }
    let texels = (0..CUBE_FACES * n * n)
        .map(|idx| {
            if weight[idx] > 0.0 {
                sum[idx].map(|v| (v / weight[idx]) as f32)
            } else {
                let (f, j, i) = (idx / (n * n), (idx / n) % n, idx % n);
                let (u, v) = equirect_position(cube_direction(
                    f,
                    (i as f32 + 0.5) / n as f32,
                    (j as f32 + 0.5) / n as f32,
                ));
                *map.get(
                    ((u * w as f32) as usize).min(w - 1),
                    ((v * h as f32) as usize).min(h - 1),
                )
            }
        })
        .collect();
    CubeLevel {
        size: n as u32,
        texels,
    }
}

/// Fills cells with zero weight by pull-push (see the module documentation), from at most
/// `levels` pyramid levels up: holes wider than about `2^levels` cells stay empty.
fn pull_push(values: &mut Raster<[f32; 3]>, weight: &mut Raster<f32>, levels: u32) {
    let (w, h) = (values.width(), values.height());
    if (w <= 1 && h <= 1) || levels == 0 {
        return;
    }
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    let mut coarse = Raster::filled(cw, ch, [0.0f32; 3]);
    let mut coarse_w = Raster::filled(cw, ch, 0.0f32);
    for y in 0..h {
        for x in 0..w {
            let wt = *weight.get(x, y);
            if wt > 0.0 {
                let c = *values.get(x, y);
                let acc = coarse.get_mut(x / 2, y / 2);
                for k in 0..3 {
                    acc[k] += c[k] * wt;
                }
                *coarse_w.get_mut(x / 2, y / 2) += wt;
            }
        }
    }
    for (c, wt) in coarse.pixels_mut().iter_mut().zip(coarse_w.pixels()) {
        if *wt > 0.0 {
            *c = c.map(|v| v / wt);
        }
    }
    if coarse_w.pixels().iter().any(|v| *v <= 0.0) && coarse_w.pixels().iter().any(|v| *v > 0.0) {
        pull_push(&mut coarse, &mut coarse_w, levels - 1);
    }
    for y in 0..h {
        for x in 0..w {
            if *weight.get(x, y) <= 0.0 && *coarse_w.get(x / 2, y / 2) > 0.0 {
                *values.get_mut(x, y) = *coarse.get(x / 2, y / 2);
                *weight.get_mut(x, y) = 1e-3;
            }
        }
    }
}

/// Pyramid levels of the pull-push that fills small holes (up to about 2^this cells wide).
const HOLE_LEVELS: u32 = 3;

/// Fills the small holes of an equirect map (cells with no weight) by pull-push from the seen
/// cells that are `copyable` (per cell, row-major), leaving every seen cell as it is. Lights and
/// their glare are seen but not copyable: an LDR lamp expanded to HDR would otherwise spill into
/// the unseen cells around it and, through them, into every band [`fill_by_elevation`] copies
/// them to. On `two-lights` with a bare table that made the unseen ceiling several times as bright
/// as the walls below it, and the SH error 79.8 % (18.5 % without the spill; docs/lights-eval.md,
/// stop 45).
fn fill_small_holes(values: &mut Raster<[f32; 3]>, weight: &mut Raster<f32>, copyable: &[bool]) {
    let mut holes = values.clone();
    let mut hole_weight = weight.clone();
    for (w, c) in hole_weight.pixels_mut().iter_mut().zip(copyable) {
        if !c {
            *w = 0.0;
        }
    }
    if !hole_weight.pixels().iter().any(|w| *w > 0.0) {
        return;
    }
    pull_push(&mut holes, &mut hole_weight, HOLE_LEVELS);
    let cells = values.pixels_mut().iter_mut().zip(weight.pixels_mut());
    for ((v, w), (hole, hw)) in cells.zip(holes.pixels().iter().zip(hole_weight.pixels())) {
        if *w <= 0.0 && *hw > 0.0 {
            *v = *hole;
            *w = *hw;
        }
    }
}

/// Elevation bands of [`fill_by_elevation`] (equal in solid angle).
const ELEVATION_BANDS: usize = 24;

/// Fills the cells of an equirect map that have no weight from the seen cells (those `copyable`
/// per cell, row-major) at the same elevation above the horizon of `up`: a room goes on around
/// the point behind the camera much as it looks in front of it, its floor below, its walls at the
/// horizon, its ceiling above. A band seen over less than [`MIN_SOURCE_COVERAGE`] of its solid
/// angle copies the nearest band seen over more (when none is, the nearest with anything seen).
///
/// Without `shading` an unseen cell takes the mean of the band it copies. With it (per cell, the relative
/// irradiance of the surface the cell looks at, [`super::relight`]), the band's surfaces are
/// relit to the cell: the band's mean times the cell's shading over the band's mean shading
/// (at most [`MAX_RELIGHT`]). A ceiling copied from the tops of walls that a ceiling light
/// grazes is then as dark as the bounce light it gets; one under lamps hanging below it, bright.
fn fill_by_elevation(
    values: &mut Raster<[f32; 3]>,
    weight: &mut Raster<f32>,
    copyable: &[bool],
    up: Vec3,
    shading: Option<&Raster<f32>>,
) {
    let (w, h) = (values.width(), values.height());
    let band_of = |x: usize, y: usize| {
        let d = equirect_direction((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
        let e = d.dot(up).clamp(-1.0, 1.0);
        (((e + 1.0) / 2.0 * ELEVATION_BANDS as f32) as usize).min(ELEVATION_BANDS - 1)
    };
    let shade = |x: usize, y: usize| shading.map_or(1.0, |s| *s.get(x, y) as f64);
    let mut sum = [[0.0f64; 3]; ELEVATION_BANDS];
    let mut shade_sum = [0.0f64; ELEVATION_BANDS];
    let mut area = [0.0f64; ELEVATION_BANDS];
    let mut sphere_area = 0.0f64;
    for y in 0..h {
        let a = (((y as f32 + 0.5) / h as f32) * std::f32::consts::PI).sin() as f64;
        sphere_area += a * w as f64;
        for x in 0..w {
            if *weight.get(x, y) > 0.0 && copyable[y * w + x] {
                let b = band_of(x, y);
                let c = values.get(x, y);
                for k in 0..3 {
                    sum[b][k] += c[k] as f64 * a;
                }
                shade_sum[b] += shade(x, y) * a;
                area[b] += a;
            }
        }
    }
    // Per band: the band it copies (mean colour, mean shading): the nearest band seen over at
    // least MIN_SOURCE_COVERAGE of its solid angle (itself when it is), since a band of which a
    // few cells are seen (a lamp's fixture, an edge) is no sample of it; when no band is, the
    // nearest band with anything seen.
    let band_area = sphere_area / ELEVATION_BANDS as f64;
    let covered = |o: usize| area[o] >= MIN_SOURCE_COVERAGE * band_area;
    let any_covered = (0..ELEVATION_BANDS).any(covered);
    let source: Vec<Option<([f64; 3], f64)>> = (0..ELEVATION_BANDS)
        .map(|b| {
            (0..ELEVATION_BANDS)
                .filter(|&o| area[o] > 0.0 && (!any_covered || covered(o)))
                .min_by_key(|&o| o.abs_diff(b))
                .map(|o| (sum[o].map(|v| v / area[o]), shade_sum[o] / area[o]))
        })
        .collect();
    for y in 0..h {
        for x in 0..w {
            if *weight.get(x, y) <= 0.0 {
                if let Some((mean, mean_shade)) = source[band_of(x, y)] {
                    let relight = if shading.is_some() && mean_shade > 1e-12 {
                        (shade(x, y) / mean_shade).clamp(0.0, MAX_RELIGHT)
                    } else {
                        1.0
                    };
                    *values.get_mut(x, y) = mean.map(|v| (v * relight) as f32);
                    *weight.get_mut(x, y) = 1e-3;
                }
            }
        }
    }
}

/// The share of a band's solid angle that must be seen for it to fill the bands that have
/// nothing seen (see [`fill_by_elevation`]).
const MIN_SOURCE_COVERAGE: f64 = 0.05;

/// The most an unseen cell is relit above the band it copies (see [`fill_by_elevation`]): a
/// proxy surface next to a lamp would otherwise take the lamp's `1/r²` peak into the map.
const MAX_RELIGHT: f64 = 4.0;

/// Steps of the ray march of [`march`] (geometric in distance).
const MARCH_STEPS: usize = 192;

/// Where each direction around a point meets the photo: one ray march through the depth map per
/// cell of the `4n × 2n` equirectangular grid of [`Environment::from_photo_with_up`] (`n` the
/// cube's face size), kept so that environments around the same point share it.
pub(crate) struct PhotoReprojection {
    face_size: u32,
    photo_size: (usize, usize),
    point: Vec3,
    /// Per cell (row-major), the photo pixel the direction meets; `None` where it meets nothing.
    hits: Vec<Option<(u32, u32)>>,
}

impl PhotoReprojection {
    /// The point the directions start from (camera frame, metres).
    pub(crate) fn point(&self) -> Vec3 {
        self.point
    }

    /// The size of the photo marched over, pixels.
    pub(crate) fn photo_size(&self) -> (usize, usize) {
        self.photo_size
    }

    /// The equirect grid: `(4n, 2n)` cells for face size `n`.
    pub(crate) fn cells(&self) -> (usize, usize) {
        let n = self.face_size as usize;
        (4 * n, 2 * n)
    }

    /// Per cell (row-major over [`PhotoReprojection::cells`]), the photo pixel its direction
    /// meets, if any.
    pub(crate) fn hits(&self) -> &[Option<(u32, u32)>] {
        &self.hits
    }

    /// Marches every direction from `point` (camera frame, metres) through `depth` (metres along
    /// the optical axis, NaN/inf = unknown: taken as infinitely far).
    ///
    /// # Errors
    /// `InvalidArgument` for an empty photo, a non-finite point or a `face_size` outside 4..=1024;
    /// `SizeMismatch` when the depth or camera is not the photo's size.
    pub(crate) fn new(
        photo: &Raster<[f32; 3]>,
        depth: Option<&Raster<f32>>,
        camera: &Camera,
        point: Vec3,
        face_size: u32,
    ) -> Result<PhotoReprojection> {
        EnvironmentOptions {
            face_size,
            ..EnvironmentOptions::default()
        }
        .validate()?;
        camera.validate()?;
        let (w, h) = check_photo_camera(photo, camera)?;
        if let Some(d) = depth {
            check_same("depth map", photo, d)?;
        }
        if !point.is_finite() {
            return Err(Error::invalid(format!(
                "environment point must be finite, got {point}"
            )));
        }
        let n = face_size as usize;
        let (ew, eh) = (4 * n, 2 * n);
        let far = depth
            .and_then(crate::camera::valid_depth_range)
            .map_or(1.0, |(_, far)| far);
        // Long enough to reach every surface of the depth map from the point.
        let reach = 2.0 * (far + point.length()) + 1.0;
        let hits = (0..ew * eh)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % ew, i / ew);
                let dir =
                    equirect_direction((x as f32 + 0.5) / ew as f32, (y as f32 + 0.5) / eh as f32);
                march(depth, camera, point, dir, reach).map(|(px, py)| (px as u32, py as u32))
            })
            .collect();
        Ok(PhotoReprojection {
            face_size,
            photo_size: (w, h),
            point,
            hits,
        })
    }
}

/// The photo pixel seen from `point` in direction `dir` (unit), by a ray march through the depth
/// map: the first sample where the ray passes from in front of the visible surface to behind it
/// by less than a thickness is a hit, and its pixel is what the point sees. A ray that passes
/// behind a surface by more than the thickness goes on (what lies behind an object is unknown
/// until the ray comes out in front again). A ray that stays in front of every surface until
/// `reach` over pixels without depth sees those (sky, far lamps: infinitely far). `None` when the
/// ray leaves the image, or ends over a surface it never met: the photo did not see that
/// direction from `point`. Without depth every pixel is infinitely far.
fn march(
    depth: Option<&Raster<f32>>,
    camera: &Camera,
    point: Vec3,
    dir: Vec3,
    reach: f32,
) -> Option<(usize, usize)> {
    let surface = |px: usize, py: usize| {
        depth
            .map(|d| *d.get(px, py))
            .filter(|z| z.is_finite() && *z > 0.0)
            .unwrap_or(f32::INFINITY)
    };
    let pixel_of = |q: Vec3| camera.project_to_pixel(q).map(|(x, y, _)| (x, y));
    let t0 = 1e-3f32;
    let ratio = (reach / t0)
        .max(1.0 + 1e-6)
        .powf(1.0 / (MARCH_STEPS - 1) as f32);
    let mut t = t0;
    let mut was_inside = false;
    // Whether the previous sample was in front of the visible surface.
    let mut in_front = false;
    let mut last_z = -point.z;
    let mut last = None;
    for _ in 0..MARCH_STEPS {
        let q = point + dir * t;
        t *= ratio;
        let z = -q.z;
        let Some((px, py)) = pixel_of(q) else {
            if was_inside {
                return None;
            }
            last_z = z;
            continue;
        };
        was_inside = true;
        last = Some((px, py));
        let zs = surface(px, py);
        if z >= zs {
            let thickness = (0.1 * zs).max(0.05).max(1.5 * (z - last_z).abs());
            if in_front && z - zs <= thickness {
                return Some((px, py));
            }
            in_front = false;
        } else {
            in_front = true;
        }
        last_z = z;
    }
    // Still in front at the end of the reach: what lies there is infinitely far, if anything.
    last.filter(|&(px, py)| in_front && surface(px, py).is_infinite())
}

impl Environment {
    /// From a cube level of linear radiance (non-finite/negative texels sanitised).
    ///
    /// # Errors
    /// `InvalidArgument` for a size of 0 or bad options; `SizeMismatch` for a wrong texel count.
    pub fn from_cube(level: &CubeLevel, options: &EnvironmentOptions) -> Result<Environment> {
        options.validate()?;
        let n = level.size as usize;
        if n == 0 || level.texels.len() != CUBE_FACES * n * n {
            return Err(Error::SizeMismatch(format!(
                "cube level of size {n} needs {} texels, got {}",
                CUBE_FACES * n * n,
                level.texels.len()
            )));
        }
        let level = CubeLevel {
            size: level.size,
            texels: level
                .texels
                .iter()
                .map(|c| sanitize(*c, HALF_MAX))
                .collect(),
        };
        Ok(Environment {
            sh9: sh9_from_cube(&level, options.max_radiance, options.sh_window),
            cube: CubeMap {
                levels: vec![level],
            },
            seen_fraction: 1.0,
            source: EnvironmentSource::Map,
        })
    }

    /// From an equirectangular HDR map (linear radiance; NaN/negative → 0, +inf → clamp).
    ///
    /// # Errors
    /// `InvalidArgument` for a map smaller than 2×1 or bad options.
    pub fn from_equirect(
        map: &Raster<[f32; 3]>,
        options: &EnvironmentOptions,
    ) -> Result<Environment> {
        options.validate()?;
        let (w, h) = check_size("environment map", map)?;
        if w < 2 {
            return Err(Error::invalid(format!(
                "environment map must be at least 2x1 pixels, got {w}x{h}"
            )));
        }
        let clean = map.map(|c| sanitize(*c, HALF_MAX));
        Environment::from_cube(
            &equirect_to_cube(&clean, options.face_size as usize),
            options,
        )
    }

    /// The photo seen from `point` (camera frame, metres), with `lights` drawn in (see the module
    /// documentation). `depth` in metres along the optical axis (NaN/inf = unknown: the pixel is
    /// taken as infinitely far).
    ///
    /// # Errors
    /// `InvalidArgument` for an empty photo, a non-finite point, an invalid light or bad options;
    /// `SizeMismatch` when the depth or camera is not the photo's size.
    pub fn from_photo(
        photo: &Raster<[f32; 3]>,
        depth: Option<&Raster<f32>>,
        camera: &Camera,
        point: Vec3,
        lights: &[Light],
        options: &EnvironmentOptions,
    ) -> Result<Environment> {
        Environment::from_photo_with_up(photo, depth, camera, point, Vec3::Y, lights, options)
    }

    /// [`Environment::from_photo`] with gravity `up` in the camera frame (the support surfaces'
    /// normal), by which the directions the photo did not show are filled.
    ///
    /// # Errors
    /// As [`Environment::from_photo`], and `InvalidArgument` for a zero or non-finite `up`.
    pub fn from_photo_with_up(
        photo: &Raster<[f32; 3]>,
        depth: Option<&Raster<f32>>,
        camera: &Camera,
        point: Vec3,
        up: Vec3,
        lights: &[Light],
        options: &EnvironmentOptions,
    ) -> Result<Environment> {
        let reprojection = PhotoReprojection::new(photo, depth, camera, point, options.face_size)?;
        Environment::from_reprojection(photo, &reprojection, up, lights, None, options)
    }

    /// [`Environment::from_photo_with_up`] from a ray march already done: several environments
    /// around the same point (another LDR expansion, other lights) share one.
    ///
    /// # Errors
    /// `InvalidArgument` for bad options (or a `face_size` other than the reprojection's), a zero
    /// or non-finite `up` or an invalid light; `SizeMismatch` when the photo is not the one
    /// marched over.
    pub(crate) fn from_reprojection(
        photo: &Raster<[f32; 3]>,
        reprojection: &PhotoReprojection,
        up: Vec3,
        lights: &[Light],
        shading: Option<&Raster<f32>>,
        options: &EnvironmentOptions,
    ) -> Result<Environment> {
        options.validate()?;
        if let Some(s) = shading {
            let cells = reprojection.cells();
            if (s.width(), s.height()) != cells {
                return Err(Error::SizeMismatch(format!(
                    "unseen-direction shading is {}x{} but the reprojection has {}x{} cells",
                    s.width(),
                    s.height(),
                    cells.0,
                    cells.1
                )));
            }
        }
        if options.face_size != reprojection.face_size {
            return Err(Error::invalid(format!(
                "environment face_size {} differs from the reprojection's {}",
                options.face_size, reprojection.face_size
            )));
        }
        if (photo.width(), photo.height()) != reprojection.photo_size {
            return Err(Error::SizeMismatch(format!(
                "photo is {}x{} but the reprojection was marched over a {}x{} one",
                photo.width(),
                photo.height(),
                reprojection.photo_size.0,
                reprojection.photo_size.1
            )));
        }
        if !(up.is_finite() && up.length() > 1e-6) {
            return Err(Error::invalid(format!(
                "environment up must be a finite non-zero vector, got {up}"
            )));
        }
        let up = up.normalize();
        for l in lights {
            l.validate()?;
        }
        let ldr = photo
            .pixels()
            .iter()
            .all(|c| c.iter().all(|v| !v.is_finite() || *v <= 1.0 + 1e-3));
        let n = options.face_size as usize;
        let (ew, eh) = (4 * n, 2 * n);
        let cells: Vec<Option<[f32; 3]>> = reprojection
            .hits
            .par_iter()
            .map(|hit| {
                hit.map(|(px, py)| {
                    let c = *photo.get(px as usize, py as usize);
                    if ldr {
                        inverse_tone_map(c, options.ldr_peak)
                    } else {
                        sanitize(c, HALF_MAX)
                    }
                })
            })
            .collect();
        // Lights and their glare (the pixels the source detector calls bright: clipped in an LDR
        // photo, near the top of the range in an HDR one): what they show at one direction says
        // nothing about the unseen directions at its elevation.
        let defaults = SourceOptions::default();
        let bright = bright_pixels(photo, defaults.saturation, defaults.hdr_fraction);
        let copyable: Vec<bool> = reprojection
            .hits
            .iter()
            .map(|hit| hit.is_none_or(|(px, py)| !*bright.get(px as usize, py as usize)))
            .collect();
        let mut weight = Raster::from_vec(
            ew,
            eh,
            cells
                .iter()
                .map(|c| if c.is_some() { 1.0f32 } else { 0.0 })
                .collect(),
        );
        let mut values = Raster::from_vec(
            ew,
            eh,
            cells.into_iter().map(|c| c.unwrap_or([0.0; 3])).collect(),
        );
        let mut seen = 0.0f64;
        let mut total = 0.0f64;
        for y in 0..eh {
            let a = (((y as f32 + 0.5) / eh as f32) * std::f32::consts::PI).sin() as f64;
            for x in 0..ew {
                total += a;
                if *weight.get(x, y) > 0.0 {
                    seen += a;
                }
            }
        }
        if seen > 0.0 {
            fill_small_holes(&mut values, &mut weight, &copyable);
            fill_by_elevation(&mut values, &mut weight, &copyable, up, shading);
        }
        let mut level = equirect_to_cube(&values, n);
        for light in lights {
            draw_light(&mut level, light, reprojection.point);
        }
        let mut env = Environment::from_cube(&level, options)?;
        env.seen_fraction = (seen / total) as f32;
        env.source = EnvironmentSource::Photo;
        Ok(env)
    }

    /// The GGX-prefiltered mip chain of the cube ([`prefilter_ggx`]), `levels` levels with
    /// `samples` samples per texel. Computed on request only: diffuse-only materials need the
    /// SH alone.
    ///
    /// # Errors
    /// As [`prefilter_ggx`].
    pub fn prefiltered(&self, levels: usize, samples: u32) -> Result<CubeMap> {
        let base = self
            .cube
            .levels
            .first()
            .ok_or_else(|| Error::Internal("environment has no cube level".into()))?;
        prefilter_ggx(base, levels, samples)
    }

    /// The cube converted to half floats RGBA (alpha 1), face after face, for an RGBA16F texture.
    pub fn cube_rgba16f(&self) -> Vec<[half::f16; 4]> {
        self.cube
            .levels
            .first()
            .map(|l| {
                l.texels
                    .iter()
                    .map(|c| {
                        let h = |v: f32| half::f16::from_f32(v.clamp(0.0, HALF_MAX));
                        [h(c[0]), h(c[1]), h(c[2]), half::f16::ONE]
                    })
                    .collect()
            })
            .unwrap_or_default()
    }
}

/// Draws a light into a cube level as a disc of its solid angle seen from `point`, whose radiance
/// gives the light's irradiance exactly (texel solid angles are exact). The disc is at least a
/// texel and a half wide, so it cannot fall between texels; its radiance is lowered to keep the
/// irradiance when it is widened. Texels keep the brighter of their value and the light's.
fn draw_light(level: &mut CubeLevel, light: &Light, point: Vec3) {
    let n = level.size as usize;
    let (towards, dist) = light.towards(point);
    let (irradiance, radius_rad) = match light.kind {
        LightKind::Directional => (light.intensity, (light.size.to_radians() / 2.0).max(1e-4)),
        LightKind::Point | LightKind::Area => {
            let d = dist.max(1e-3);
            // Facing factor of an area disc: cosine between its axis and the way to the point.
            let facing = if light.kind == LightKind::Area {
                (-towards)
                    .dot(Vec3::from(light.direction).normalize_or_zero())
                    .max(0.0)
            } else {
                1.0
            };
            (
                light.intensity.map(|i| i * facing / (d * d)),
                (light.size / 2.0 / d).atan().max(1e-4),
            )
        }
    };
    let texel = 2.0 / n as f32;
    let cos_r = radius_rad.max(1.5 * texel).cos();
    let mut cells = Vec::new();
    let mut omega = 0.0f32;
    for f in 0..CUBE_FACES {
        for j in 0..n {
            for i in 0..n {
                let d = cube_direction(f, (i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                if d.dot(towards) >= cos_r {
                    cells.push(f * n * n + j * n + i);
                    omega += texel_solid_angle(i, j, n);
                }
            }
        }
    }
    if cells.is_empty() || omega <= 0.0 {
        return;
    }
    let radiance = irradiance.map(|e| (e / omega).min(HALF_MAX));
    for idx in cells {
        let c = &mut level.texels[idx];
        for k in 0..3 {
            c[k] = c[k].max(radiance[k]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    #[test]
    fn constant_map_gives_constant_sh_and_cube() {
        let env = Environment::from_equirect(
            &Raster::filled(64, 32, [0.5f32, 1.0, 2.0]),
            &Default::default(),
        )
        .unwrap();
        for n in [Vec3::X, -Vec3::Y, Vec3::new(0.3, 0.5, -0.8).normalize()] {
            let d = env.sh9.diffuse_radiance(n);
            assert!(
                (d[0] - 0.5).abs() < 0.01 && (d[2] - 2.0).abs() < 0.02,
                "{d:?}"
            );
        }
        assert!(env.cube.levels[0]
            .texels
            .iter()
            .all(|t| (t[1] - 1.0).abs() < 1e-5));
    }

    #[test]
    fn sky_above_ground_below_gives_the_analytic_irradiance() {
        // Radiance 1 from the upper hemisphere only: irradiance on an up-facing surface is π
        // (diffuse radiance 1), on a down-facing one 0, on a vertical one π/2 (0.5).
        let map = Raster::from_fn(256, 128, |_, y| if y < 64 { [1.0f32; 3] } else { [0.0; 3] });
        let env = Environment::from_equirect(&map, &Default::default()).unwrap();
        let up = env.sh9.diffuse_radiance(Vec3::Y)[0];
        let side = env.sh9.diffuse_radiance(Vec3::X)[0];
        let down = env.sh9.diffuse_radiance(-Vec3::Y)[0];
        // A 9-term fit of a step: within a few percent of the truth.
        assert!((up - 1.0).abs() < 0.06, "{up}");
        assert!((side - 0.5).abs() < 0.03, "{side}");
        assert!(down < 0.06, "{down}");
    }

    #[test]
    fn a_tiny_megawatt_sun_stays_finite_and_bounded() {
        let mut map = Raster::filled(512, 256, [0.1f32; 3]);
        *map.get_mut(300, 60) = [1e6; 3];
        *map.get_mut(10, 10) = [f32::NAN, f32::INFINITY, -3.0];
        let sun = equirect_direction(300.5 / 512.0, 60.5 / 256.0);
        for window in [0.0, 1.0] {
            let options = EnvironmentOptions {
                sh_window: window,
                ..Default::default()
            };
            let env = Environment::from_equirect(&map, &options).unwrap();
            assert!(env.sh9.to_array().iter().all(|v| v.is_finite()));
            // Sample the irradiance over the sphere: bounded by the clamp's contribution, and
            // the ringing opposite the sun stays small relative to the peak.
            let (mut lo, mut hi) = (f32::MAX, f32::MIN);
            for i in 0..500 {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / 500.0;
                let phi = i as f32 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                let n = Vec3::new(r * phi.cos(), z, r * phi.sin());
                let p = super::super::model::sh9_basis_polynomials(n);
                let v: f32 = env
                    .sh9
                    .coefficients
                    .iter()
                    .zip(p)
                    .map(|(c, w)| c[0] * w)
                    .sum();
                lo = lo.min(v);
                hi = hi.max(v);
            }
            // One clamped texel of 1000 over ~4π/24576 sr adds at most ~0.05 to the radiance.
            assert!(hi < 0.1 + 0.2, "window {window}: max {hi}");
            assert!(lo > -0.05 * hi, "window {window}: min {lo} vs max {hi}");
            // The brightest direction is the sun's.
            let towards = env.sh9.diffuse_radiance(sun)[0];
            assert!(towards >= 0.95 * hi);
            // The cube keeps the sun (up to half-float range) for glossy reflections.
            let peak = env.cube.levels[0]
                .texels
                .iter()
                .map(|t| t[0])
                .fold(0.0, f32::max);
            assert!(peak > 1000.0 && peak <= HALF_MAX);
        }
    }

    #[test]
    fn photo_reprojection_sees_the_floor_below_and_fills_behind() {
        // A camera 1 m above a floor (y = −1) of radiance 0.3; the sky (no depth) is 0.7.
        let camera = Camera::from_focal(40.0, 80, 60).unwrap();
        let depth = Raster::from_fn(80, 60, |_, y| {
            let dv = y as f32 + 0.5 - camera.cy;
            if dv > 0.5 {
                camera.fy / dv
            } else {
                f32::NAN
            }
        });
        let photo = Raster::from_fn(80, 60, |_, y| {
            if (y as f32 + 0.5) > camera.cy + 0.5 {
                [0.3f32; 3]
            } else {
                [0.7; 3]
            }
        });
        let point = Vec3::new(0.0, -0.9, -3.0);
        let env = Environment::from_photo(
            &photo,
            Some(&depth),
            &camera,
            point,
            &[],
            &Default::default(),
        )
        .unwrap();
        assert!(
            env.seen_fraction > 0.1 && env.seen_fraction < 0.9,
            "{}",
            env.seen_fraction
        );
        let down = env.sh9.diffuse_radiance(-Vec3::Y)[0];
        let up = env.sh9.diffuse_radiance(Vec3::Y)[0];
        assert!((down - 0.3).abs() < 0.08, "{down}");
        assert!((up - 0.7).abs() < 0.12, "{up}");
        // Drawing a directional light adds its irradiance on a surface facing it.
        let sun = Light::directional([0.0, -1.0, 0.0], 2.0, [PI; 3]);
        let lit = Environment::from_photo(
            &photo,
            Some(&depth),
            &camera,
            point,
            &[sun],
            &Default::default(),
        )
        .unwrap();
        let gain = lit.sh9.diffuse_radiance(Vec3::Y)[0] - up;
        assert!((gain - 1.0).abs() < 0.1, "{gain}");
    }

    /// A camera 1.25 m above a floor (radiance 0.7) looking along −Z at a table top 0.5 m below
    /// it (radiance 0.2) spanning z ∈ [−3.5, −1.5] and the whole width; sky (no depth, 0.5)
    /// above the horizon. Values below the LDR knee, so none is expanded.
    fn table_scene() -> (Camera, Raster<f32>, Raster<[f32; 3]>) {
        let camera = Camera::from_focal(60.0, 120, 90).unwrap();
        let hit = |x: usize, y: usize| -> (f32, [f32; 3]) {
            let d = camera.ray_direction(x as f32 + 0.5, y as f32 + 0.5);
            if d.y < 0.0 {
                let t = -0.5 / d.y;
                let z = d.z * t;
                if (-3.5..=-1.5).contains(&z) {
                    return (-z, [0.2; 3]);
                }
                return (-d.z * (-1.25 / d.y), [0.7; 3]);
            }
            (f32::NAN, [0.5; 3])
        };
        let depth = Raster::from_fn(120, 90, |x, y| hit(x, y).0);
        let photo = Raster::from_fn(120, 90, |x, y| hit(x, y).1);
        (camera, depth, photo)
    }

    #[test]
    fn a_surface_just_below_the_point_hides_what_lies_beyond_it() {
        // 2 cm above the table's centre, the whole lower hemisphere is table (0.2): the brighter
        // floor the camera sees in front of the table is hidden from the point by the table, though
        // the table covers only a few pixels in those directions.
        let (camera, depth, photo) = table_scene();
        let point = Vec3::new(0.0, -0.48, -2.5);
        let env = Environment::from_photo(
            &photo,
            Some(&depth),
            &camera,
            point,
            &[],
            &Default::default(),
        )
        .unwrap();
        let down = env.sh9.diffuse_radiance(-Vec3::Y)[0];
        assert!((down - 0.2).abs() < 0.03, "facing down: {down}");
        // Every texel looking more than 20° below the horizon is table.
        let level = &env.cube.levels[0];
        let n = level.size as usize;
        for (idx, t) in level.texels.iter().enumerate() {
            let (f, j, i) = (idx / (n * n), (idx / n) % n, idx % n);
            let d = cube_direction(f, (i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            if d.y < -0.35 {
                assert!((t[0] - 0.2).abs() < 1e-4, "{d}: {t:?}");
            }
        }
    }

    #[test]
    fn a_ray_passing_behind_an_object_goes_on_to_what_is_behind() {
        // A pillar (0.6, 20 cm wide, 2 m away) in front of a wall (0.3, 5 m away); from a point
        // between them, a ray that crosses behind the pillar (1.75 m behind its front) meets the
        // wall, and one towards the pillar's front from the camera's side sees the pillar.
        let camera = Camera::from_focal(60.0, 120, 90).unwrap();
        let pillar = |x: usize| ((x as f32 + 0.5 - camera.cx) * 2.0 / camera.fx).abs() < 0.1;
        let depth = Raster::from_fn(120, 90, |x, _| if pillar(x) { 2.0 } else { 5.0 });
        let photo = Raster::from_fn(
            120,
            90,
            |x, _| if pillar(x) { [0.6f32; 3] } else { [0.3; 3] },
        );
        let point = Vec3::new(0.3, 0.0, -3.0);
        let env = Environment::from_photo(
            &photo,
            Some(&depth),
            &camera,
            point,
            &[],
            &Default::default(),
        )
        .unwrap();
        let level = &env.cube.levels[0];
        let behind =
            super::super::prefilter::sample_cube(level, Vec3::new(-0.8, 0.0, -2.0).normalize());
        assert!((behind[0] - 0.3).abs() < 1e-4, "{behind:?}");
        // From a point in front of the pillar, towards it.
        let front = Environment::from_photo(
            &photo,
            Some(&depth),
            &camera,
            Vec3::new(0.3, 0.0, -1.0),
            &[],
            &Default::default(),
        )
        .unwrap();
        let towards = super::super::prefilter::sample_cube(
            &front.cube.levels[0],
            Vec3::new(-0.3, 0.0, -1.0).normalize(),
        );
        assert!((towards[0] - 0.6).abs() < 1e-4, "{towards:?}");
    }

    #[test]
    fn unseen_directions_take_what_was_seen_at_their_elevation() {
        // Behind the camera, below the horizon, the floor goes on (0.7 in front of the table, seen
        // from a point above it); above the horizon the sky (0.5).
        let (camera, depth, photo) = table_scene();
        let point = Vec3::new(0.0, -0.3, -1.0);
        let env = Environment::from_photo_with_up(
            &photo,
            Some(&depth),
            &camera,
            point,
            Vec3::Y,
            &[],
            &Default::default(),
        )
        .unwrap();
        let level = &env.cube.levels[0];
        let at = |d: Vec3| {
            let (f, s, t) = cube_texel(d);
            let n = level.size as usize;
            level.texels[f * n * n
                + ((t * n as f32) as usize).min(n - 1) * n
                + ((s * n as f32) as usize).min(n - 1)][0]
        };
        let behind_below = at(Vec3::new(0.0, -0.8, 1.0).normalize());
        let behind_above = at(Vec3::new(0.3, 0.5, 1.0).normalize());
        assert!((behind_below - 0.7).abs() < 0.05, "{behind_below}");
        assert!((behind_above - 0.5).abs() < 0.05, "{behind_above}");
        // A tilted `up` is checked.
        assert!(Environment::from_photo_with_up(
            &photo,
            Some(&depth),
            &camera,
            point,
            Vec3::ZERO,
            &[],
            &Default::default(),
        )
        .unwrap_err()
        .to_string()
        .contains("up"));
    }

    /// An equirect map of 64 × 32 cells: `seen(direction)` gives a seen cell's value, `None`
    /// leaves it unseen; and the elevation of each cell's direction above +Y.
    fn band_map(seen: impl Fn(Vec3) -> Option<f32>) -> (Raster<[f32; 3]>, Raster<f32>, Vec<f32>) {
        let (w, h) = (64, 32);
        let direction = |x: usize, y: usize| {
            equirect_direction((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32)
        };
        let values = Raster::from_fn(w, h, |x, y| [seen(direction(x, y)).unwrap_or(0.0); 3]);
        let weight = Raster::from_fn(w, h, |x, y| {
            if seen(direction(x, y)).is_some() {
                1.0
            } else {
                0.0
            }
        });
        let elevation = (0..w * h).map(|i| direction(i % w, i / w).y).collect();
        (values, weight, elevation)
    }

    /// The cells of a [`band_map`] below 1: lamps and clipped windows (≥ 1) are not copyable.
    fn copyable_below_one(values: &Raster<[f32; 3]>) -> Vec<bool> {
        values.pixels().iter().map(|c| c[0] < 1.0).collect()
    }

    /// Asserts that every cell of a [`band_map`] above elevation `above` holds `want`.
    fn assert_above(values: &Raster<[f32; 3]>, elevation: &[f32], above: f32, want: f32) {
        let w = values.width();
        for (i, e) in elevation.iter().enumerate() {
            if *e > above {
                let v = values.get(i % w, i / w)[0];
                assert!((v - want).abs() < 1e-5, "elevation {e}: {v}");
            }
        }
    }

    #[test]
    fn unseen_bands_copy_well_seen_bands_not_stray_or_clipped_cells() {
        // Walls (0.2) seen up to 30° above the horizon, a few bright cells of a lamp fixture just
        // above them, nothing higher: the ceiling copies the walls, not the fixture (the nearest
        // band with anything seen, which the fill took before).
        let fixture = |d: Vec3| d.y > 0.55 && d.y < 0.7 && d.x > 0.0 && d.z < 0.0 && d.x < 0.2;
        let (mut values, mut weight, elevation) = band_map(|d| {
            if fixture(d) {
                Some(3.0)
            } else {
                (d.y < 0.5).then_some(0.2)
            }
        });
        let fixture_cells = (0..values.len())
            .filter(|&i| *weight.get(i % 64, i / 64) > 0.0 && elevation[i] > 0.5)
            .count();
        assert!(
            (1..=8).contains(&fixture_cells),
            "{fixture_cells} fixture cells"
        );
        let copyable = vec![true; values.len()];
        fill_by_elevation(&mut values, &mut weight, &copyable, Vec3::Y, None);
        assert_above(&values, &elevation, 0.7, 0.2);
        // Clipped cells are not copied: half of the walls' top band a bright window, marked as
        // not copyable; the rest of that band and the ceiling take the walls' 0.2.
        let window = |d: Vec3| d.y > 0.3 && d.y < 0.5 && d.x > 0.0;
        let (mut values, mut weight, elevation) = band_map(|d| {
            if window(d) {
                Some(1.0)
            } else {
                (d.y < 0.5).then_some(0.2)
            }
        });
        let copyable = copyable_below_one(&values);
        fill_by_elevation(&mut values, &mut weight, &copyable, Vec3::Y, None);
        assert_above(&values, &elevation, 0.5, 0.2);
    }

    #[test]
    fn a_lamp_does_not_spill_into_the_holes_around_it() {
        // Walls (0.2) seen up to 30° above the horizon, a clipped lamp (8, not copyable) in them,
        // and a small hole beside the lamp that the pull-push fills: from the walls, not the
        // lamp, and the ceiling, which copies the top of the walls with the filled hole in it,
        // stays at the walls' 0.2.
        let lamp = |d: Vec3| d.y > 0.3 && d.y < 0.45 && d.z < 0.0 && d.x > 0.0 && d.x < 0.15;
        let hole = |d: Vec3| d.y > 0.3 && d.y < 0.45 && d.z < 0.0 && d.x >= 0.15 && d.x < 0.3;
        let (mut values, mut weight, elevation) = band_map(|d| {
            if lamp(d) {
                Some(8.0)
            } else if hole(d) {
                None
            } else {
                (d.y < 0.5).then_some(0.2)
            }
        });
        let (w, h) = (values.width(), values.height());
        let copyable = copyable_below_one(&values);
        let lamp_cells = copyable.iter().filter(|c| !**c).count();
        let hole_cells: Vec<usize> = (0..w * h)
            .filter(|&i| *weight.get(i % w, i / w) == 0.0 && (0.3..0.45).contains(&elevation[i]))
            .collect();
        assert!(
            lamp_cells >= 1 && !hole_cells.is_empty(),
            "{lamp_cells} {hole_cells:?}"
        );
        fill_small_holes(&mut values, &mut weight, &copyable);
        for &i in &hole_cells {
            let v = values.get(i % w, i / w)[0];
            assert!((v - 0.2).abs() < 1e-5, "hole cell {i}: {v}");
        }
        fill_by_elevation(&mut values, &mut weight, &copyable, Vec3::Y, None);
        assert_above(&values, &elevation, 0.7, 0.2);
        // The lamp itself is still in the map.
        let lamp_kept = (0..w * h)
            .filter(|&i| values.get(i % w, i / w)[0] == 8.0)
            .count();
        assert_eq!(lamp_kept, lamp_cells);
    }

    #[test]
    fn clipped_pixels_of_an_ldr_photo_are_not_copied_to_unseen_directions() {
        // The sky rows between 20° and 35° above the horizon clipped (a bright window): behind
        // the camera at that elevation the map shows the sky as without them, not the window.
        let (camera, depth, photo) = table_scene();
        let clipped = Raster::from_fn(photo.width(), photo.height(), |x, y| {
            let d = camera
                .ray_direction(x as f32 + 0.5, y as f32 + 0.5)
                .normalize();
            if d.y > 0.34 && d.y < 0.57 {
                [1.0; 3]
            } else {
                *photo.get(x, y)
            }
        });
        let point = Vec3::new(0.0, -0.3, -1.0);
        let behind = Vec3::new(0.3, 0.5, 1.0).normalize();
        let at = |photo: &Raster<[f32; 3]>| {
            let env = Environment::from_photo(
                photo,
                Some(&depth),
                &camera,
                point,
                &[],
                &Default::default(),
            )
            .unwrap();
            super::super::prefilter::sample_cube(&env.cube.levels[0], behind)[0]
        };
        let (plain, with_window) = (at(&photo), at(&clipped));
        assert!(
            (with_window - plain).abs() < 1e-3 * plain,
            "{with_window} against {plain}"
        );
    }

    #[test]
    fn unseen_cells_are_relit_by_their_shading_within_a_cap() {
        // Walls of 0.3 seen below 30°, under shading 2; the unseen ceiling under shading 1 takes
        // half of them, a cell under shading 100 at most 4×.
        let (mut values, mut weight, elevation) = band_map(|d| (d.y < 0.5).then_some(0.3));
        let (w, h) = (values.width(), values.height());
        let bright = w * 2 + 5;
        assert!(elevation[bright] > 0.9);
        let shading = Raster::from_fn(w, h, |x, y| {
            let i = y * w + x;
            if i == bright {
                100.0
            } else if elevation[i] < 0.5 {
                2.0
            } else {
                1.0
            }
        });
        let copyable = vec![true; w * h];
        fill_by_elevation(&mut values, &mut weight, &copyable, Vec3::Y, Some(&shading));
        for (i, e) in elevation.iter().enumerate() {
            let v = values.get(i % w, i / w)[0];
            let want = if i == bright {
                0.3 * MAX_RELIGHT as f32
            } else if *e < 0.5 {
                0.3
            } else {
                0.15
            };
            assert!(
                (v - want).abs() < 1e-5,
                "cell {i}, elevation {e}: {v}, want {want}"
            );
        }
    }

    #[test]
    fn one_reprojection_serves_environments_of_other_expansions_and_lights() {
        let (camera, depth, photo) = table_scene();
        let point = Vec3::new(0.0, -0.3, -1.0);
        let options = EnvironmentOptions::default();
        let shared =
            PhotoReprojection::new(&photo, Some(&depth), &camera, point, options.face_size)
                .unwrap();
        let lamp = Light {
            kind: LightKind::Point,
            position: [0.2, 0.5, -1.5],
            direction: [0.0, -1.0, 0.0],
            size: 0.1,
            intensity: [3.0; 3],
            confidence: 1.0,
        };
        for (lights, peak) in [(vec![], 1.0), (vec![lamp], options.ldr_peak)] {
            let options = EnvironmentOptions {
                ldr_peak: peak,
                ..options
            };
            let direct = Environment::from_photo_with_up(
                &photo,
                Some(&depth),
                &camera,
                point,
                Vec3::Y,
                &lights,
                &options,
            )
            .unwrap();
            let from_shared =
                Environment::from_reprojection(&photo, &shared, Vec3::Y, &lights, None, &options)
                    .unwrap();
            assert_eq!(direct, from_shared);
        }
        // The reprojection belongs to one face size and one photo size.
        let other_size = EnvironmentOptions {
            face_size: options.face_size / 2,
            ..options
        };
        let err = Environment::from_reprojection(&photo, &shared, Vec3::Y, &[], None, &other_size)
            .unwrap_err();
        assert!(err.to_string().contains("face_size"), "{err}");
        let small = Raster::filled(4, 4, [0.5f32; 3]);
        assert!(matches!(
            Environment::from_reprojection(&small, &shared, Vec3::Y, &[], None, &options),
            Err(Error::SizeMismatch(_))
        ));
    }

    #[test]
    fn ldr_expansion_is_continuous_and_reaches_the_peak() {
        assert_eq!(inverse_tone_map([0.5; 3], 8.0), [0.5; 3]);
        assert!((inverse_tone_map([1.0; 3], 8.0)[0] - 8.0).abs() < 1e-5);
        assert!((inverse_tone_map([0.8001; 3], 8.0)[0] - 0.8001).abs() < 1e-3);
        assert_eq!(
            inverse_tone_map([f32::NAN, -1.0, 3.0], 8.0)[0..2],
            [0.0, 0.0]
        );
    }

    #[test]
    fn bad_input_is_named() {
        let e = Environment::from_equirect(&Raster::filled(1, 1, [0.0f32; 3]), &Default::default())
            .unwrap_err();
        assert!(e.to_string().contains("environment map"));
        let bad = EnvironmentOptions {
            face_size: 2,
            ..Default::default()
        };
        assert!(
            Environment::from_equirect(&Raster::filled(8, 4, [0.0f32; 3]), &bad)
                .unwrap_err()
                .to_string()
                .contains("face_size")
        );
        let camera = Camera::from_focal(10.0, 8, 6).unwrap();
        let e = Environment::from_photo(
            &Raster::filled(8, 6, [0.0f32; 3]),
            None,
            &camera,
            Vec3::NAN,
            &[],
            &Default::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("point"));
        // Black and tiny photos give a finite (black) environment.
        let env = Environment::from_photo(
            &Raster::filled(8, 6, [0.0f32; 3]),
            None,
            &camera,
            Vec3::ZERO,
            &[],
            &Default::default(),
        )
        .unwrap();
        assert!(env
            .sh9
            .to_array()
            .iter()
            .all(|v| v.is_finite() && v.abs() < 1e-6));
        let one = Camera::from_focal(1.0, 1, 1).unwrap();
        let env = Environment::from_photo(
            &Raster::filled(1, 1, [1e6f32; 3]),
            None,
            &one,
            Vec3::ZERO,
            &[],
            &Default::default(),
        )
        .unwrap();
        assert!(env.sh9.to_array().iter().all(|v| v.is_finite()));
        assert_eq!(env.cube_rgba16f().len(), 6 * 64 * 64);
    }
}
