//! Lights out of view, by inverse rendering (thesis §3.3.4, extended): the directional or point
//! light and ambient term that best explain the shading of the photo's surfaces given their
//! normals, in agreement with the cast shadows of the shadow mask; in-view sources are re-scaled on
//! the way.
//!
//! Model, per sample pixel `i` on a continuous region `s` (Lambertian, one albedo per region):
//! `Y_i = ρ_s · (A + Σ_j E_j · g_j(i))`, with `g_j = max(0, n·l_j) · V_j` for a directional light
//! and `max(0, n·l_j) · V_j / r_j²` (times the disc's facing cosine) for a light at a position.
//! Visibility `V_j` is traced through the depth map (a screen-space ray march from the point
//! towards the light: occluded when the ray passes behind a visible surface by less than a
//! thickness, unless that surface is the light's own body), so cast shadows are part of the model:
//! a direction whose shadows fall where the photo has none explains the shading worse. For a fixed
//! set of lights the fit alternates between the light intensities `E`, `A` (non-negative least
//! squares) and the albedos `ρ_s`.
//!
//! The out-of-view light is searched among candidates seen from the insertion point: directions
//! over the sphere above the horizon (Fibonacci points) for a directional light, and, more
//! coarsely (a quarter as many directions), points at 0.5, 1 and 2 times the median distance from
//! the insertion point to the samples for a point light (a room's lamp hangs about as far away as
//! its walls), each position only when the insertion point sees it (not behind a surface of the
//! photo) and the camera does not (in the frame, in front of what the photo shows there, it would
//! be in the photo, where no source was detected). Each
//! candidate is scored by the relative RMS residual plus how its predicted cast shadows (the part
//! of the direct light hidden from a sample: of the candidate's, and of the in-view lights' with
//! it at their fitted intensities, since the mask shows every light's shadows and where two lights
//! reach a surface the shadow of one is only as dark as its share) compare with the shadow mask,
//! *against predicting no shadow*: a predicted shadow where the mask has one lowers the score, one
//! where the mask has none raises it, and a shadow of the mask that the model does not predict
//! counts for neither, since ambient light alone (which predicts none) does not explain it either.
//! Such shadows are common: their casters may be out of view (a window's wall) or missing from a
//! noisy stereo depth map, and charging them to the candidate alone made the fit fall back where
//! the light was found. The in-view lights alone, the baseline a candidate must improve on, are
//! scored the same way. The best of each
//! kind is then refined: a direction over a set four times as dense around it; a position by a
//! pattern search over its three coordinates (a step along either tangent of its direction and its
//! distance scaled by a factor, the step halved and the factor square-rooted when no step
//! improves, down to 0.5°, the distance kept within a factor of two of the candidates'): a nearby lamp
//! shows itself in how its light falls off and turns across the floor, which no single direction
//! explains, and three coordinates on a grid would cost too many scores. The point light replaces
//! the best direction only when it scores lower by the margin a light must bring over none
//! (`FitOptions::min_improvement`): its extra parameter, the distance, lets a weak nearby light
//! fit a local gradient (a sunlit patch, the falloff along a wall) that is no lamp. Its
//! angular size, as seen from the insertion point, is chosen among a few cone widths by the same
//! score (wider cones give softer predicted shadows). A candidate counts only when at least 10 % of
//! the samples face it unoccluded within 75.5° (cos ≥ 0.25): of a light that only grazes what the
//! photo shows, only intensity × a small cosine is measured, and an object facing it would be lit
//! by an arbitrary extrapolation.
//!
//! ## A second out-of-view light
//! Two lights out of view (a ceiling lamp and a bulb on the other side) are not one light: a single
//! fitted light stands in for both from between them, or from where their shading overlaps (in
//! `two-lights` with the camera tilted down, straight above the table). So, unless
//! `FitOptions::max_out_of_view` is 1, a second light is searched the same way beside the first
//! (the first held as a fixed light, its intensity refitted with the rest; not when the first
//! search found no candidate that lights enough of the photo), and then the first
//! again beside the second, so that it can move from the stand-in's place to the light it belongs
//! to. The pair replaces the single light only when its score is lower than the single light's
//! and than the baseline's by the margin a light must bring (`FitOptions::min_improvement`), both
//! of its lights are fitted to some light, and the weaker gives at least a tenth of the
//! stronger's light at the insertion point (a fainter one changes little of how an inserted object
//! is lit, and the pair's search finds such faint lights in the small gradients a single light
//! leaves). The search is greedy: where the first light sits between two similar lights, the
//! second search may find neither, and the single light stays. It costs two more searches, whose
//! candidates' visibility marches are those of the first search, kept for them.
//!
//! Albedo and light intensity are only known up to a common factor: the fit fixes the median
//! region albedo to `FitOptions::albedo` (0.5 by default). The colours of the in-view sources and
//! of the ambient term come from the same fit per channel under the grey-world assumption (the
//! median albedo is grey); the fitted out-of-view lights are kept neutral, since their colour
//! trades off against the ambient term's and the few regions they light.
//!
//! When nothing can be inferred (too few usable pixels, or no candidate light explains the shading
//! better than ambient light alone and the in-view sources, if any, are all fitted to no light),
//! the thesis' fallback is used: one light above the scene, and [`LightFit::fallback_used`] says
//! so, so the caller can warn.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use glam::Vec3;
use rayon::prelude::*;

use super::filters::{check_photo_camera, check_same, luminance};
use super::model::{Light, LightKind};
use super::shadow_mask::NO_REGION;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::image::Raster;

/// What the fit looks at. Every raster has the photo's size.
#[derive(Debug, Clone, Copy)]
pub struct FitInputs<'a> {
    /// Linear RGB photo (1.0 = white).
    pub photo: &'a Raster<[f32; 3]>,
    /// Depth along the optical axis, metres (NaN/inf = unknown).
    pub depth: &'a Raster<f32>,
    /// Unit normals in the camera frame (zero = unknown).
    pub normals: &'a Raster<[f32; 3]>,
    /// Continuous regions ([`crate::light::continuity_regions`]); [`NO_REGION`] pixels are not
    /// used.
    pub regions: &'a Raster<u32>,
    /// Soft shadow mask in [0, 1] ([`crate::light::shadow_mask()`]), if any.
    pub shadow_mask: Option<&'a Raster<f32>>,
    /// The camera.
    pub camera: &'a Camera,
    /// Gravity up, camera frame.
    pub up: [f32; 3],
}

/// Options of [`fit_lights`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// At most this many sample pixels (≥ 100).
    pub max_samples: usize,
    /// Candidate directions in the coarse search (≥ 16); a quarter as many carry the point-light
    /// candidates, and their spacing is the first step of the point light's refinement.
    pub directions: usize,
    /// The assumed median albedo of the regions, in (0, 1].
    pub albedo: f32,
    /// Weight in the score of the shadow term: what a model's predicted cast shadows cost or earn
    /// against the shadow mask, compared with predicting none (see the module documentation; ≥ 0).
    pub shadow_weight: f32,
    /// Relative improvement over ambient (plus in-view lights) that the fitted out-of-view light must
    /// bring to be kept, and that a point light must bring over the best direction to replace it,
    /// in [0, 1).
    pub min_improvement: f32,
    /// Where the main light is judged from (camera frame, metres): the light giving the most
    /// irradiance there is the main one. Point-light candidates are placed around it and the
    /// fitted light's angular size is seen from it. `None`: the median sample point.
    pub insertion_point: Option<[f32; 3]>,
    /// At most this many out-of-view lights, 1 or 2 (default 2): a second one is searched beside
    /// the first and kept only when the pair beats the first alone, and ambient light alone, by
    /// `min_improvement` (see the module documentation).
    pub max_out_of_view: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            max_samples: 4000,
            directions: 300,
            albedo: 0.5,
            shadow_weight: 0.5,
            min_improvement: 0.1,
            insertion_point: None,
            max_out_of_view: 2,
        }
    }
}

impl FitOptions {
    /// Checks ranges.
    ///
    /// # Errors
    /// `InvalidArgument` naming the option out of range.
    pub fn validate(&self) -> Result<()> {
        if self.max_samples < 100 || self.max_samples > 1_000_000 {
            return Err(Error::invalid(format!(
                "fit max_samples must be in 100..=1000000, got {}",
                self.max_samples
            )));
        }
        if self.directions < 16 || self.directions > 100_000 {
            return Err(Error::invalid(format!(
                "fit directions must be in 16..=100000, got {}",
                self.directions
            )));
        }
        if !(self.albedo > 0.0 && self.albedo <= 1.0) {
            return Err(Error::invalid(format!(
                "fit albedo must be in (0, 1], got {}",
                self.albedo
            )));
        }
        if !(self.shadow_weight >= 0.0 && self.shadow_weight.is_finite()) {
            return Err(Error::invalid(format!(
                "fit shadow_weight must be finite and >= 0, got {}",
                self.shadow_weight
            )));
        }
        if !(0.0..1.0).contains(&self.min_improvement) {
            return Err(Error::invalid(format!(
                "fit min_improvement must be in [0, 1), got {}",
                self.min_improvement
            )));
        }
        if !(1..=2).contains(&self.max_out_of_view) {
            return Err(Error::invalid(format!(
                "fit max_out_of_view must be 1 or 2, got {}",
                self.max_out_of_view
            )));
        }
        if let Some(p) = self.insertion_point {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(Error::invalid(format!(
                    "fit insertion_point must be finite, got {p:?}"
                )));
            }
        }
        Ok(())
    }
}

/// The result of [`fit_lights`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LightFit {
    /// The light that gives the most irradiance at the insertion point.
    pub main: Light,
    /// Uniform ambient light as the diffuse radiance of a white surface (linear RGB).
    pub ambient: [f32; 3],
    /// Every light: the in-view sources the fit gives light to (re-scaled; those it fits to no
    /// light explain nothing and are left out), then the fitted out-of-view lights, if kept (at
    /// most [`FitOptions::max_out_of_view`]).
    pub lights: Vec<Light>,
    /// True when nothing could be inferred and the main light is the "one light above the
    /// scene" fallback.
    pub fallback_used: bool,
    /// Relative RMS error of the shading model on the samples (luminance), ≥ 0.
    pub residual: f32,
    /// Mean disagreement between predicted cast shadows and the mask, in [0, 1] (0 without one).
    pub shadow_disagreement: f32,
    /// Number of sample pixels used.
    pub samples: usize,
}

/// A sample supports an out-of-view candidate light when it faces the light, unoccluded, at least
/// this much (the cosine, 0.25: within 75.5° of the light).
const SUPPORT_COSINE: f32 = 0.25;

/// Fraction of the samples that must support an out-of-view candidate light for it to be inferred.
const MIN_SUPPORT: f64 = 0.1;

/// Distances of the positional candidates for the out-of-view light, relative to the median
/// distance from the insertion point to the samples.
const POINT_DISTANCES: [f32; 3] = [0.5, 1.0, 2.0];

/// The refinement of a positional light stops when its angular step falls below this (0.5°).
const POINT_REFINE_STOP_RAD: f32 = 0.5 * std::f32::consts::PI / 180.0;

/// The refinement of a positional light takes at most this many rounds of steps, so that a score
/// that keeps improving by tiny amounts cannot hold it up.
const POINT_REFINE_MAX_ROUNDS: usize = 100;

/// The coarse search of positional candidates uses this many times fewer directions than the
/// directional one.
const POINT_DIRECTION_DIVISOR: usize = 4;

/// A sample faces a light for the shadow comparison when the cosine towards it exceeds this: at
/// grazing angles the light's share of the shading, and so its shadow, is too faint to judge.
const FACING_COSINE: f32 = 0.15;

/// A second out-of-view light is kept only when it gives at least this share of the other's light
/// at the insertion point ([`irradiance_at`]): a fainter one changes little of how an inserted
/// object is lit, and the pair's search finds such faint lights where the first light leaves a
/// small gradient unexplained.
const MIN_SECOND_LIGHT_SHARE: f32 = 0.1;

/// Largest relative residual of a fit that is still taken as an inference of the light.
const MAX_EXPLAINED_RESIDUAL: f64 = 0.5;

/// A candidate light as scored by the fit.
struct Scored {
    /// Relative RMS residual plus the weighted shadow term (lower is better).
    score: f64,
    /// The residual alone.
    residual: f64,
    /// Mean disagreement of its predicted shadows with the mask, in [0, 1].
    disagreement: f64,
    /// Its light on each sample, with cast shadows, at unit intensity.
    column: Vec<f32>,
}

struct Sample {
    p: Vec3,
    n: Vec3,
    rgb: [f32; 3],
    region: usize,
    mask: f32,
}

/// `σ_w` of a depth map's inverse depth (1/m), measured as the mesh's normal fit measures it; 0
/// when it cannot be (too few valid pixels).
fn depth_noise(depth: &Raster<f32>) -> f32 {
    let w = crate::mesh::local_fit::inverse_depth(depth);
    crate::mesh::local_fit::correlated_noise(&w).map_or(0.0, |n| n.sigma as f32)
}

/// What can shadow a sample: the depth map seen through the camera, and how noisy it is.
#[derive(Clone, Copy)]
struct Occluders<'a> {
    depth: &'a Raster<f32>,
    camera: &'a Camera,
    /// Standard deviation of the depth map's inverse depth, 1/m (stereo noise; ~0 when exact).
    sigma_w: f32,
}

/// How many standard deviations of depth noise a ray must pass behind the depth map to count as
/// occluded. On a noisy floor one σ keeps 96 % of the lit floor lit (88 % without a margin) and
/// still finds half of a box's cast shadow; two σ find 99 % and 17 %.
const OCCLUSION_NOISE_SIGMAS: f32 = 1.0;

/// Screen-space visibility from `p` (normal `n`) towards `l` up to `max_dist` metres. A ray point
/// is occluded when it lies behind the depth map by more than 1 % + 1 cm plus the depth noise
/// there (`σ_Z = Z²·σ_w`), within a thickness of 15 % + 5 cm. `emitter` (centre, reach) is the
/// light's own body ([`Light::body_reach`]): depth-map surfaces within it do not occlude.
fn visible(
    occluders: &Occluders,
    p: Vec3,
    n: Vec3,
    l: Vec3,
    max_dist: f32,
    emitter: Option<(Vec3, f32)>,
) -> bool {
    const STEPS: usize = 40;
    let camera = occluders.camera;
    let z0 = -p.z;
    let noise = |z: f32| OCCLUSION_NOISE_SIGMAS * occluders.sigma_w * z * z;
    let origin = p + n * (0.01 * z0 + 0.005 + noise(z0));
    let t0 = (0.01 * z0).max(0.01);
    if max_dist <= t0 {
        return true;
    }
    let ratio = (max_dist / t0).powf(1.0 / (STEPS - 1) as f32);
    let mut t = t0;
    for _ in 0..STEPS {
        let q = origin + l * t;
        t *= ratio;
        let Some((uv, zq)) = camera.project(q) else {
            return true;
        };
        if uv.x < 0.0 || uv.y < 0.0 || uv.x >= camera.width as f32 || uv.y >= camera.height as f32 {
            return true;
        }
        let zs = *occluders.depth.get(uv.x as usize, uv.y as usize);
        if zs.is_finite() && zs > 0.0 {
            let behind = zq - zs - noise(zs);
            if behind > zs * 0.01 + 0.01 && behind < zs * 0.15 + 0.05 {
                let own_body = emitter.is_some_and(|(centre, reach)| {
                    camera
                        .unproject(uv.x, uv.y, zs)
                        .is_some_and(|surface| surface.distance(centre) <= reach)
                });
                if !own_body {
                    return false;
                }
            }
        }
    }
    true
}

/// Unoccluded geometric term of a light at a sample (see the module documentation), with the
/// unit direction towards the light and how far a visibility march must go; `None` when the
/// sample faces away or lies behind an area light.
fn geometry(light: &Light, s: &Sample, reach: f32) -> Option<(f32, Vec3, f32)> {
    let shade = light.unshadowed_term(s.p, s.n);
    if shade <= 0.0 {
        return None;
    }
    let (l, dist) = light.towards(s.p);
    let max_dist = match light.kind {
        LightKind::Directional => reach,
        LightKind::Point | LightKind::Area => (dist * 0.95).min(reach),
    };
    Some((shade, l, max_dist))
}

/// The body of a light at a position (centre, reach), for [`visible`].
fn body(light: &Light) -> Option<(Vec3, f32)> {
    (light.kind != LightKind::Directional).then(|| (Vec3::from(light.position), light.body_reach()))
}

/// A light's geometric term at a sample with its cast shadows and without, and whether the
/// sample faces it enough to judge its shadow (cos > [`FACING_COSINE`]).
fn terms(light: &Light, s: &Sample, occluders: &Occluders, reach: f32) -> (f32, f32, bool) {
    match geometry(light, s, reach) {
        Some((shade, l, max_dist)) => {
            let lit = visible(occluders, s.p, s.n, l, max_dist, body(light));
            (
                if lit { shade } else { 0.0 },
                shade,
                s.n.dot(l) > FACING_COSINE,
            )
        }
        None => (0.0, 0.0, false),
    }
}

/// How a model's predicted cast shadows compare with the shadow mask, as sums over the samples
/// facing a light divided by the number of all samples.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ShadowComparison {
    /// Mean |predicted − mask|: every shadow missed or invented, in [0, 1].
    disagreement: f64,
    /// `disagreement` less the mask on the same samples, which is what predicting no shadow there
    /// would disagree, in [−1, 1]: what the model's shadows cost (positive) or earn (negative)
    /// against ambient light alone. A shadow of the mask the model misses counts for neither.
    against_none: f64,
}

/// Compares the predicted shadow on each sample with the mask ([`ShadowComparison`]), over the
/// samples facing a light (cos > 0.15: towards `towards(sample)` for the candidate light, whose
/// lit and unoccluded terms are `lit_open`). The predicted shadow is the
/// part of the direct light hidden from the sample: of the candidate's alone (1 − lit ÷
/// unoccluded) when no other light reaches the sample; with other lights (`others`: their direct
/// light on each sample facing them, lit and unoccluded, at their fitted intensities; the
/// candidate's intensity is `weight`), of the sum. The mask shows every light's shadows, and
/// where two lights reach a surface, the shadow of one is only as dark as that light's share.
fn compare_shadows(
    samples: &[Sample],
    lit_open: &[(f32, f32, f32)],
    others: &[(f32, f32)],
    weight: f32,
    towards: impl Fn(&Sample) -> Vec3,
) -> ShadowComparison {
    let (disagreement, mask): (f64, f64) = samples
        .iter()
        .zip(lit_open)
        .zip(others)
        .map(|((s, (lit, open, _)), (other_lit, other_open))| {
            let faces = *open > 0.0 && s.n.dot(towards(s)) > FACING_COSINE;
            let (lit, open) = match (faces, *other_open > 0.0) {
                (_, false) if faces => (*lit, *open),
                (_, false) => return (0.0, 0.0),
                (true, true) => (weight * lit + other_lit, weight * open + other_open),
                (false, true) => (*other_lit, *other_open),
            };
            let predicted = 1.0 - (lit / open).clamp(0.0, 1.0);
            ((predicted - s.mask).abs() as f64, s.mask as f64)
        })
        .fold((0.0, 0.0), |(d, m), (di, mi)| (d + di, m + mi));
    let n = samples.len().max(1) as f64;
    ShadowComparison {
        disagreement: disagreement / n,
        against_none: (disagreement - mask) / n,
    }
}

/// Solves the augmented system `[A | b]` (Gauss–Jordan with partial pivoting; a singular column
/// gets 0).
fn solve(mut a: Vec<Vec<f64>>) -> Vec<f64> {
    let d = a.len();
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += 1e-12 * (1.0 + row[i].abs());
    }
    for col in 0..d {
        let pivot = (col..d)
            .max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))
            .unwrap_or(col);
        a.swap(col, pivot);
        let p = a[col][col];
        if p.abs() < 1e-300 {
            continue;
        }
        for r in 0..d {
            if r != col {
                let f = a[r][col] / p;
                let pivot_row = a[col].clone();
                for (x, y) in a[r][col..=d].iter_mut().zip(&pivot_row[col..=d]) {
                    *x -= f * y;
                }
            }
        }
    }
    (0..d)
        .map(|i| {
            let v = if a[i][i].abs() > 1e-300 {
                a[i][d] / a[i][i]
            } else {
                0.0
            };
            if v.is_finite() {
                v
            } else {
                0.0
            }
        })
        .collect()
}

/// Result of the alternating fit for one channel.
struct ChannelFit {
    /// Intensities per light, then the ambient.
    x: Vec<f64>,
    residual: f64,
}

/// The fit's design matrix `G`: a row per sample, a column per light (its term at unit
/// intensity) and the ambient term's 1 last. Stored flat: candidates are scored by the thousand,
/// and a vector per row was an allocation per sample each time.
struct Design {
    values: Vec<f32>,
    columns: usize,
}

impl Design {
    /// The rows, in sample order.
    fn rows(&self) -> std::slice::ChunksExact<'_, f32> {
        self.values.chunks_exact(self.columns)
    }

    /// The rows at `indices`, in that order.
    fn select(&self, indices: &[usize]) -> Design {
        let c = self.columns;
        Design {
            values: indices
                .iter()
                .flat_map(|&i| &self.values[i * c..(i + 1) * c])
                .copied()
                .collect(),
            columns: c,
        }
    }
}

/// Per-region sums of the system `y = ρ_region · (G x)` (Σ y·g, Σ g·gᵀ, Σ y²), from which
/// [`projected`]'s residual follows without going over the samples again: the intensity search
/// evaluates it a few hundred times per candidate. Stored flat, region after region, since a
/// photo can have hundreds of regions.
struct RegionSums {
    /// Per region: Σ y_i g_i (one entry per column of G).
    yg: Vec<f64>,
    /// Per region: Σ g_i g_iᵀ, row-major.
    gg: Vec<f64>,
    /// Per region: Σ y_i².
    yy: Vec<f64>,
    columns: usize,
}

/// The residual of one region with albedo fitted, from its Σ y·(Gx), Σ (Gx)² and Σ y²
/// (a negative best albedo is clamped to 0).
fn region_residual(ys: f64, ss: f64, yy: f64) -> f64 {
    let r = if ss > 1e-15 { (ys / ss).max(0.0) } else { 0.0 };
    (yy - 2.0 * r * ys + r * r * ss).max(0.0)
}

impl RegionSums {
    fn new(g: &Design, y: &[f32], regions: &[usize], n_regions: usize) -> RegionSums {
        let k = g.columns;
        let mut sums = RegionSums {
            yg: vec![0.0; n_regions * k],
            gg: vec![0.0; n_regions * k * k],
            yy: vec![0.0; n_regions],
            columns: k,
        };
        for ((row, &yi), &s) in g.rows().zip(y).zip(regions) {
            let yi = yi as f64;
            sums.yy[s] += yi * yi;
            let yg = &mut sums.yg[s * k..(s + 1) * k];
            let gg = &mut sums.gg[s * k * k..(s + 1) * k * k];
            for (a, &ga) in row.iter().enumerate() {
                let ga = ga as f64;
                yg[a] += yi * ga;
                for (b, &gb) in row.iter().enumerate() {
                    gg[a * k + b] += ga * gb as f64;
                }
            }
        }
        sums
    }

    /// The residual along the line where `x[j]` varies and the other entries stay: per region,
    /// Σ y·(Gx) and Σ (Gx)² are a line and a parabola in `x[j]`, so each point of a line search
    /// costs O(regions) instead of O(regions × lights²).
    fn along(&self, x: &[f64], j: usize) -> RegionLine {
        let k = self.columns;
        let mut coefficients = Vec::with_capacity(self.yy.len());
        for (s, &yy) in self.yy.iter().enumerate() {
            let yg = &self.yg[s * k..(s + 1) * k];
            let gg = &self.gg[s * k * k..(s + 1) * k * k];
            let (mut ys0, mut ss0, mut cross) = (0.0, 0.0, 0.0);
            for a in (0..k).filter(|&a| a != j) {
                ys0 += yg[a] * x[a];
                cross += gg[a * k + j] * x[a];
                for b in (0..k).filter(|&b| b != j) {
                    ss0 += x[a] * gg[a * k + b] * x[b];
                }
            }
            coefficients.push([ys0, yg[j], ss0, 2.0 * cross, gg[j * k + j], yy]);
        }
        RegionLine { coefficients }
    }
}

/// [`RegionSums::along`]: per region, Σ y·(Gx) = `c[0] + c[1]·t`, Σ (Gx)² = `c[2] + c[3]·t +
/// c[4]·t²` and Σ y² = `c[5]`, with `t` the varying entry.
struct RegionLine {
    coefficients: Vec<[f64; 6]>,
}

impl RegionLine {
    /// The residual at `x[j] = t`.
    fn residual(&self, t: f64) -> f64 {
        self.coefficients
            .iter()
            .map(|c| region_residual(c[0] + c[1] * t, c[2] + t * (c[3] + c[4] * t), c[5]))
            .sum()
    }
}

/// Residual of `y = ρ_region · (G x)` with each region's best albedo (variable projection: for
/// fixed `x` the albedos are a closed-form least-squares solution), and those albedos.
fn projected(
    g: &Design,
    y: &[f32],
    regions: &[usize],
    n_regions: usize,
    x: &[f64],
) -> (f64, Vec<f64>) {
    let mut ys = vec![0.0f64; n_regions];
    let mut ss = vec![0.0f64; n_regions];
    let mut yy = vec![0.0f64; n_regions];
    for ((row, &yi), &s) in g.rows().zip(y).zip(regions) {
        let shade: f64 = row.iter().zip(x).map(|(a, b)| *a as f64 * b).sum();
        ys[s] += yi as f64 * shade;
        ss[s] += shade * shade;
        yy[s] += (yi as f64).powi(2);
    }
    let mut err = 0.0;
    let rho: Vec<f64> = (0..n_regions)
        .map(|s| {
            err += region_residual(ys[s], ss[s], yy[s]);
            if ss[s] > 1e-15 {
                (ys[s] / ss[s]).max(0.0)
            } else {
                0.0
            }
        })
        .collect();
    (err, rho)
}

/// Fits `y = ρ_region · (G x)` with x ≥ 0 (the last column of G is the ambient's 1). The scale
/// of `x` against `ρ` is free, so the ambient is held at 1 while each light's intensity is found
/// by golden-section search over `x_j = c_j · tan(u·π/2)`, u ∈ [0, 1) (three rounds, cyclically);
/// then the scale is fixed by the median albedo.
fn alternate(
    g: &Design,
    y: &[f32],
    regions: &[usize],
    n_regions: usize,
    albedo: f32,
) -> ChannelFit {
    let k = g.columns;
    let mut x = vec![0.0f64; k];
    x[k - 1] = 1.0;
    let sums = RegionSums::new(g, y, regions, n_regions);
    // Typical size of each light's term, so that u = 0.5 means "as bright as the ambient".
    let scale: Vec<f64> = (0..k - 1)
        .map(|j| {
            let (sum, n) = g.rows().fold((0.0f64, 0usize), |(s, n), r| {
                if r[j] > 0.0 {
                    (s + r[j] as f64, n + 1)
                } else {
                    (s, n)
                }
            });
            if n > 0 && sum > 0.0 {
                n as f64 / sum
            } else {
                1.0
            }
        })
        .collect();
    for _ in 0..3 {
        for j in 0..k - 1 {
            let line = sums.along(&x, j);
            let value = |u: f64| scale[j] * (u * std::f64::consts::FRAC_PI_2).tan();
            let eval = |u: f64| line.residual(value(u));
            let (mut a, mut b) = (0.0f64, 0.999f64);
            let phi = 0.618_033_988_75;
            let (mut c, mut d) = (b - phi * (b - a), a + phi * (b - a));
            let (mut fc, mut fd) = (eval(c), eval(d));
            for _ in 0..40 {
                if fc < fd {
                    b = d;
                    d = c;
                    fd = fc;
                    c = b - phi * (b - a);
                    fc = eval(c);
                } else {
                    a = c;
                    c = d;
                    fc = fd;
                    d = a + phi * (b - a);
                    fd = eval(d);
                }
            }
            // Zero is a candidate of its own (the light may not be needed).
            let u = if eval(0.0) <= fc.min(fd) {
                0.0
            } else {
                (a + b) / 2.0
            };
            x[j] = value(u);
        }
    }
    let (err, rho) = projected(g, y, regions, n_regions, &x);
    let total: f64 = y.iter().map(|v| (*v as f64).powi(2)).sum();
    // Fix the scale: the sample-weighted median albedo becomes `albedo`.
    let mut per_sample: Vec<f64> = regions.iter().map(|&s| rho[s]).collect();
    let median = if per_sample.is_empty() {
        0.0
    } else {
        let mid = per_sample.len() / 2;
        *per_sample.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    if median > 1e-12 {
        let s = median / albedo as f64;
        x.iter_mut().for_each(|v| *v *= s);
    } else {
        x.iter_mut().for_each(|v| *v = 0.0);
    }
    ChannelFit {
        x,
        residual: if total > 0.0 {
            (err / total).sqrt()
        } else {
            0.0
        },
    }
}

/// [`alternate`], then again without the 10 % of samples the first fit explains worst: shadow
/// edges a pixel off and unmodelled highlights would otherwise pull the light's contrast down.
fn trimmed(g: &Design, y: &[f32], regions: &[usize], n_regions: usize, albedo: f32) -> ChannelFit {
    let first = alternate(g, y, regions, n_regions, albedo);
    let (_, rho) = projected(g, y, regions, n_regions, &first.x);
    let mut err: Vec<(f64, usize)> = g
        .rows()
        .zip(y)
        .zip(regions)
        .enumerate()
        .map(|(i, ((row, &yi), &s))| {
            let shade: f64 = row.iter().zip(&first.x).map(|(a, b)| *a as f64 * b).sum();
            ((yi as f64 - rho[s] * shade).abs(), i)
        })
        .collect();
    err.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let keep = err.len() * 9 / 10;
    if keep < 20 {
        return first;
    }
    let idx: Vec<usize> = err[..keep].iter().map(|e| e.1).collect();
    let g2 = g.select(&idx);
    let y2: Vec<f32> = idx.iter().map(|&i| y[i]).collect();
    let r2: Vec<usize> = idx.iter().map(|&i| regions[i]).collect();
    let second = alternate(&g2, &y2, &r2, n_regions, albedo);
    ChannelFit {
        x: second.x,
        residual: first.residual,
    }
}

/// Two unit vectors perpendicular to the unit vector `d` and to each other.
fn tangents(d: Vec3) -> (Vec3, Vec3) {
    let t = if d.x.abs() < 0.9 { Vec3::X } else { Vec3::Z };
    let x = t.cross(d).normalize();
    (x, d.cross(x))
}

/// Fibonacci points on the unit sphere with `d · up ≥ min_up`.
fn fibonacci(count: usize, up: Vec3, min_up: f32) -> Vec<Vec3> {
    let (tx, ty) = tangents(up);
    // Enough points on the whole sphere that about `count` land in the cap.
    let total = ((2.0 * count as f32) / (1.0 - min_up).max(0.05)).ceil() as usize;
    (0..total)
        .filter_map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / total as f32;
            if z < min_up {
                return None;
            }
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = i as f32 * 2.399_963_2;
            Some(tx * r * phi.cos() + ty * r * phi.sin() + up * z)
        })
        .collect()
}

/// Fits the lights (see the module documentation). `in_view` are the sources found in the photo
/// ([`crate::light::detect_sources`]); their positions are kept and their intensities re-fitted,
/// and those fitted to no light are left out of [`LightFit::lights`].
///
/// # Errors
/// `SizeMismatch` when a raster is not the photo's size or the camera's; `InvalidArgument` for an
/// empty photo, bad options, a bad camera, a zero up vector or an invalid in-view light.
pub fn fit_lights(inputs: &FitInputs, in_view: &[Light], options: &FitOptions) -> Result<LightFit> {
    let cache = SearchCache::default();
    let first = fit_beside(inputs, in_view, 0, options, &cache)?;
    if options.max_out_of_view < 2 {
        return Ok(first.fit);
    }
    let Some(one) = first.candidate.as_ref() else {
        return Ok(first.fit);
    };
    // The second light is searched beside the first, then the first again beside the second:
    // alone, the first stood in for both (two lamps on either side make one light from
    // between them), and beside the second it can move to the light it belongs to. These
    // searches keep any improvement; the pair is judged as a whole below.
    let open = FitOptions {
        min_improvement: 0.0,
        ..*options
    };
    let beside = |light: Light| fit_beside(inputs, &[in_view, &[light]].concat(), 1, &open, &cache);
    let second = beside(one.light)?;
    let Some(two) = second.candidate.as_ref() else {
        return Ok(first.fit);
    };
    let pair = beside(two.light)?;
    // The pair must bring the margin a light must bring over none, over the first light alone
    // as well as over the baseline, and hand on both of its lights, the weaker giving a share of
    // the stronger's light at the insertion point that an inserted object would show.
    let margin = 1.0 - options.min_improvement as f64;
    let out_of_view = &pair.fit.lights[pair.fit.lights.len().saturating_sub(2)..];
    let weaker_share = match out_of_view {
        [a, b] => {
            let (ea, eb) = (irradiance_at(a, pair.centre), irradiance_at(b, pair.centre));
            ea.min(eb) / ea.max(eb).max(f32::MIN_POSITIVE)
        }
        _ => 0.0,
    };
    let pair_wins = pair.kept
        && pair.fixed_kept.last() == Some(&true)
        && weaker_share >= MIN_SECOND_LIGHT_SHARE
        && pair
            .candidate
            .as_ref()
            .is_some_and(|c| c.score < first.baseline * margin && c.score < one.score * margin);
    Ok(if pair_wins { pair.fit } else { first.fit })
}

/// What the searches of one [`fit_lights`] call share, since they look at the same samples and
/// depth map:
/// - the per-sample terms (lit, unoccluded, facing cosine) of the candidate lights already
///   scored, keyed by the candidate's cone of directions and its distance. They depend on the
///   samples and the candidate only, not on the fixed lights beside it, so the pair's searches
///   reuse most of the first search's visibility marches, which are most of its cost. Candidates
///   are scored in parallel; the lock is held only to look a candidate up and to store its
///   terms, never while they are computed;
/// - the depth map's noise, measured once: a second-difference ladder over the whole map, which
///   each of the up to three searches measured again (24–27 ms each on Motorcycle's 741×497).
#[derive(Default)]
struct SearchCache {
    terms: Mutex<HashMap<Vec<u32>, SampleTerms>>,
    depth_noise: OnceLock<f32>,
}

/// Per sample: a candidate's light with cast shadows, without, and the facing cosine.
type SampleTerms = Arc<Vec<(f32, f32, f32)>>;

impl SearchCache {
    /// [`depth_noise`] of `depth`, measured on the first call (every search of one call gets
    /// the same depth map).
    fn depth_noise(&self, depth: &Raster<f32>) -> f32 {
        *self.depth_noise.get_or_init(|| depth_noise(depth))
    }

    /// The cached terms of the candidate, or `compute`'s, stored for the next search.
    fn get_or_insert(
        &self,
        cone: &[Vec3],
        distance: Option<f32>,
        compute: impl FnOnce() -> Vec<(f32, f32, f32)>,
    ) -> SampleTerms {
        let key: Vec<u32> = cone
            .iter()
            .flat_map(|d| d.to_array())
            .chain(distance)
            .map(f32::to_bits)
            .collect();
        // The map stays whole if a thread panicked while holding the lock: entries are inserted
        // complete.
        let lock = || self.terms.lock().unwrap_or_else(PoisonError::into_inner);
        let cached = lock().get(&key).cloned();
        cached.unwrap_or_else(|| {
            let terms = Arc::new(compute());
            lock().insert(key, terms.clone());
            terms
        })
    }
}

/// An out-of-view light as [`fit_beside`] found it, before the decision to keep it.
struct Candidate {
    /// Its kind, direction or position, size and confidence, at unit intensity.
    light: Light,
    /// Its score beside the fixed lights (lower is better; finite).
    score: f64,
}

/// One search for an out-of-view light beside fixed ones, and the fit it ends in.
struct OneFit {
    fit: LightFit,
    /// Score of the fixed lights and ambient light alone.
    baseline: f64,
    /// The best out-of-view light found, kept or not; none when no candidate lit enough of the
    /// photo to be scored.
    candidate: Option<Candidate>,
    /// Whether `fit` holds the candidate.
    kept: bool,
    /// Whether `fit` holds each fixed light (those fitted to no light are left out).
    fixed_kept: Vec<bool>,
    /// Where the main light was judged from (the insertion point, or the median sample point).
    centre: Vec3,
}

/// A light's luminance at `point`, unoccluded and facing it: how the main light is chosen.
fn irradiance_at(light: &Light, point: Vec3) -> f32 {
    let (_, d) = light.towards(point);
    let fall = if d.is_finite() {
        1.0 / (d * d).max(1e-4)
    } else {
        1.0
    };
    luminance(light.intensity) * fall
}

/// The fit of one out-of-view light beside `fixed_lights` (see the module documentation): the
/// in-view sources, then, when `held_neutral` > 0, that many out-of-view lights of an earlier
/// search, whose colour is held neutral as the fitted light's is. The comments below call all of
/// them the in-view lights: the fit treats them alike (positions kept, intensities refitted,
/// their shadows part of the prediction).
fn fit_beside(
    inputs: &FitInputs,
    fixed_lights: &[Light],
    held_neutral: usize,
    options: &FitOptions,
    cache: &SearchCache,
) -> Result<OneFit> {
    options.validate()?;
    inputs.camera.validate()?;
    let (w, h) = check_photo_camera(inputs.photo, inputs.camera)?;
    check_same("depth map", inputs.photo, inputs.depth)?;
    check_same("normal map", inputs.photo, inputs.normals)?;
    check_same("region map", inputs.photo, inputs.regions)?;
    if let Some(m) = inputs.shadow_mask {
        check_same("shadow mask", inputs.photo, m)?;
    }
    let up = Vec3::from(inputs.up);
    if !up.is_finite() || up.length() < 1e-6 {
        return Err(Error::invalid(format!(
            "fit up must be a finite non-zero vector, got {:?}",
            inputs.up
        )));
    }
    let up = up.normalize();
    for l in fixed_lights {
        l.validate()?;
    }

    // Samples on a regular grid.
    let stride = ((w * h) as f64 / options.max_samples as f64)
        .sqrt()
        .ceil()
        .max(1.0) as usize;
    let mut region_index = HashMap::new();
    let mut samples = Vec::new();
    for y in (stride / 2..h).step_by(stride) {
        for x in (stride / 2..w).step_by(stride) {
            let region = *inputs.regions.get(x, y);
            let n = Vec3::from(*inputs.normals.get(x, y));
            let rgb = *inputs.photo.get(x, y);
            if region == NO_REGION || !n.is_finite() || (n.length() - 1.0).abs() > 0.05 {
                continue;
            }
            if !rgb.iter().all(|v| v.is_finite() && *v >= 0.0)
                || rgb.iter().any(|v| *v >= 0.98) && rgb.iter().all(|v| *v <= 1.0)
            {
                // Clipped pixels carry no shading information.
                continue;
            }
            let Some(p) =
                inputs
                    .camera
                    .unproject(x as f32 + 0.5, y as f32 + 0.5, *inputs.depth.get(x, y))
            else {
                continue;
            };
            let next = region_index.len();
            let r = *region_index.entry(region).or_insert(next);
            let mask = inputs.shadow_mask.map_or(0.0, |m| {
                let v = *m.get(x, y);
                if v.is_finite() {
                    v.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            });
            samples.push(Sample {
                p,
                n: n.normalize(),
                rgb,
                region: r,
                mask,
            });
        }
    }
    // Drop regions with too few samples to have an albedo of their own.
    let mut counts = vec![0usize; region_index.len()];
    for s in &samples {
        counts[s.region] += 1;
    }
    samples.retain(|s| counts[s.region] >= 8);
    let mut remap = vec![usize::MAX; counts.len()];
    let mut n_regions = 0;
    for s in &mut samples {
        if remap[s.region] == usize::MAX {
            remap[s.region] = n_regions;
            n_regions += 1;
        }
        s.region = remap[s.region];
    }
    let regions: Vec<usize> = samples.iter().map(|s| s.region).collect();
    let luma: Vec<f32> = samples.iter().map(|s| luminance(s.rgb)).collect();
    let mut depths: Vec<f32> = samples.iter().map(|s| -s.p.z).collect();
    let centre = match options.insertion_point {
        Some(p) => Vec3::from(p),
        None if !samples.is_empty() => {
            let mut xs: Vec<f32> = samples.iter().map(|s| s.p.x).collect();
            let mut ys: Vec<f32> = samples.iter().map(|s| s.p.y).collect();
            let mut zs: Vec<f32> = samples.iter().map(|s| s.p.z).collect();
            let med = |v: &mut Vec<f32>| {
                let mid = v.len() / 2;
                *v.select_nth_unstable_by(mid, f32::total_cmp).1
            };
            Vec3::new(med(&mut xs), med(&mut ys), med(&mut zs))
        }
        None => Vec3::new(0.0, 0.0, -1.0),
    };
    let reach = if depths.is_empty() {
        1.0
    } else {
        let mid = depths.len() / 2;
        2.0 * *depths.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    let occluders = Occluders {
        depth: inputs.depth,
        camera: inputs.camera,
        sigma_w: cache.depth_noise(inputs.depth),
    };

    // Each in-view light's term per sample with and without cast shadows (its column is the
    // former), and whether the sample faces it enough to judge its shadow.
    let fixed_terms: Vec<Vec<(f32, f32, bool)>> = fixed_lights
        .iter()
        .map(|l| {
            samples
                .par_iter()
                .map(|s| terms(l, s, &occluders, reach))
                .collect()
        })
        .collect();
    let build = |extra: Option<&Vec<f32>>| -> Design {
        let columns = fixed_terms.len() + extra.is_some() as usize + 1;
        let mut values = Vec::with_capacity(samples.len() * columns);
        for i in 0..samples.len() {
            values.extend(fixed_terms.iter().map(|c| c[i].0));
            if let Some(e) = extra {
                values.push(e[i]);
            }
            values.push(1.0);
        }
        Design { values, columns }
    };
    // `kept`: the in-view sources that stay, with their detected intensities (the fallback only
    // stands in for what could not be inferred).
    let fallback = |samples_used: usize, kept: &[Light]| -> LightFit {
        // The thesis' fallback: one light above the scene, half of the mean brightness from it.
        let mean = if luma.is_empty() {
            [0.0; 3]
        } else {
            let mut m = [0.0f32; 3];
            for s in &samples {
                for (acc, v) in m.iter_mut().zip(s.rgb) {
                    *acc += v / samples.len() as f32;
                }
            }
            m
        };
        let ambient = mean.map(|v| 0.5 * v / options.albedo);
        let mut main = Light::directional(
            (-up).to_array(),
            30.0,
            mean.map(|v| std::f32::consts::PI * 0.5 * v / options.albedo),
        );
        main.confidence = 0.1;
        let mut lights = kept.to_vec();
        lights.push(main);
        LightFit {
            main,
            ambient,
            lights,
            fallback_used: true,
            residual: 1.0,
            shadow_disagreement: 0.0,
            samples: samples_used,
        }
    };
    let nothing_found = |fit: LightFit, baseline: f64| OneFit {
        fit,
        baseline,
        candidate: None,
        kept: false,
        fixed_kept: vec![false; fixed_lights.len()],
        centre,
    };
    if samples.len() < 50 || n_regions == 0 || luma.iter().all(|v| *v <= 1e-6) {
        return Ok(nothing_found(
            fallback(samples.len(), fixed_lights),
            f64::INFINITY,
        ));
    }

    // The in-view lights' direct light on each sample facing them, at intensities `x` (their
    // first entries), with and without their cast shadows: their part of the predicted shadows.
    let in_view_direct = |x: &[f64]| -> Vec<(f32, f32)> {
        (0..samples.len())
            .map(|i| {
                fixed_terms
                    .iter()
                    .zip(x)
                    .filter(|(c, _)| c[i].2)
                    .fold((0.0, 0.0), |(lit, open), (c, x)| {
                        (lit + c[i].0 * *x as f32, open + c[i].1 * *x as f32)
                    })
            })
            .collect()
    };
    // Baseline: ambient plus the in-view lights, scored like a candidate (their shadows against
    // the mask; none without in-view lights).
    let baseline = alternate(&build(None), &luma, &regions, n_regions, options.albedo);
    let has_mask = inputs.shadow_mask.is_some();
    let baseline_score = if has_mask && !fixed_lights.is_empty() {
        let no_candidate = vec![(0.0, 0.0, 0.0); samples.len()];
        let shadows = compare_shadows(
            &samples,
            &no_candidate,
            &in_view_direct(&baseline.x),
            0.0,
            |_| Vec3::ZERO,
        );
        baseline.residual + options.shadow_weight as f64 * shadows.against_none
    } else {
        baseline.residual
    };
    // The out-of-view light seen from the insertion point: towards `d` at `distance` metres, or
    // infinitely far (a directional light).
    let candidate_light = |d: Vec3, distance: Option<f32>| match distance {
        None => Light::directional((-d).to_array(), 0.0, [1.0; 3]),
        Some(r) => Light::point((centre + d * r).to_array(), 0.0, [1.0; 3]),
    };
    let score_candidate = |cone: &[Vec3], distance: Option<f32>| -> Scored {
        // Per sample: the cone's light with cast shadows, without, and the facing cosine towards
        // the cone's axis when unoccluded (the support test needs the cosine alone: the light
        // term of a point light also falls off with 1/r²).
        let per_sample = cache.get_or_insert(cone, distance, || {
            samples
                .par_iter()
                .map(|s| {
                    let (mut lit, mut open, mut facing) = (0.0, 0.0, 0.0);
                    for (k, d) in cone.iter().enumerate() {
                        let light = candidate_light(*d, distance);
                        if let Some((shade, l, max_dist)) = geometry(&light, s, reach) {
                            open += shade;
                            if visible(&occluders, s.p, s.n, l, max_dist, None) {
                                lit += shade;
                                if k == 0 {
                                    facing = s.n.dot(l);
                                }
                            }
                        }
                    }
                    (lit / cone.len() as f32, open / cone.len() as f32, facing)
                })
                .collect()
        });
        let column: Vec<f32> = per_sample.iter().map(|v| v.0).collect();
        // A light is inferred only from surfaces it lights: one that reaches the photo's
        // surfaces at grazing angles alone explains a faint gradient with any intensity, and
        // lights an object facing it (what the renderer then shows) by that extrapolation.
        let supported = per_sample.iter().filter(|v| v.2 >= SUPPORT_COSINE).count();
        if (supported as f64) < MIN_SUPPORT * samples.len() as f64 {
            return Scored {
                score: f64::INFINITY,
                residual: f64::INFINITY,
                disagreement: 0.0,
                column,
            };
        }
        let fit = alternate(
            &build(Some(&column)),
            &luma,
            &regions,
            n_regions,
            options.albedo,
        );
        // Predicted cast shadow (the part of the direct light hidden from the sample) against
        // the mask on the samples facing a light, scored against predicting no shadow there.
        let shadows = if has_mask {
            let axis_light = candidate_light(cone[0], distance);
            let others = in_view_direct(&fit.x);
            let weight = fit.x[fixed_lights.len()] as f32;
            compare_shadows(&samples, &per_sample, &others, weight, |s| {
                axis_light.towards(s.p).0
            })
        } else {
            ShadowComparison {
                disagreement: 0.0,
                against_none: 0.0,
            }
        };
        Scored {
            score: fit.residual + options.shadow_weight as f64 * shadows.against_none,
            residual: fit.residual,
            disagreement: shadows.disagreement,
            column,
        }
    };
    // A light at a position must be in the open as seen from the insertion point (not behind a
    // surface of the photo), and out of the camera's sight: inside the frame and in front of what
    // the photo shows there, it would be in the photo, where the detector found no source.
    let in_the_open = |d: Vec3, distance: Option<f32>| {
        distance.is_none_or(|r| {
            let position = centre + d * r;
            // Unknown depth there (NaN, infinite) counts as nothing in front of the lamp.
            let seen_by_camera =
                inputs
                    .camera
                    .project_to_pixel(position)
                    .is_some_and(|(x, y, z)| {
                        let surface = *inputs.depth.get(x, y);
                        surface.is_nan() || surface >= z
                    });
            !seen_by_camera && visible(&occluders, centre, d, d, r, None)
        })
    };
    // Distances of the positional candidates, in units of the median distance from the
    // insertion point to the photo's surfaces (a room's lamps hang about as far away as its
    // walls).
    let spread = {
        let mut r: Vec<f32> = samples.iter().map(|s| s.p.distance(centre)).collect();
        let mid = r.len() / 2;
        r.select_nth_unstable_by(mid, f32::total_cmp).1.max(1e-3)
    };
    let point_distances = POINT_DISTANCES.map(|f| f * spread);
    // The refinement stays within a factor of two of the candidates' distances: nearer, the lamp
    // closes in on the insertion point; farther, it is a direction.
    let (min_distance, max_distance) = (point_distances[0] / 2.0, point_distances[2] * 2.0);
    type Best = Option<(f64, Vec3, Option<f32>)>;
    // Candidates are scored in parallel, then taken in their order: the first of equal scores
    // wins, as it would one after another, so the result does not depend on the threads.
    let consider = |best: &mut Best, candidates: &[(Vec3, Option<f32>)]| {
        let scores: Vec<Option<f64>> = candidates
            .par_iter()
            .map(|&(d, distance)| {
                in_the_open(d, distance).then(|| score_candidate(&[d], distance).score)
            })
            .collect();
        for (&(d, distance), score) in candidates.iter().zip(scores) {
            if let Some(score) = score {
                if best.is_none_or(|(b, _, _)| score < b) {
                    *best = Some((score, d, distance));
                }
            }
        }
    };
    // The best direction: a coarse search over the sphere above the horizon, then one four times
    // as dense within about two coarse spacings of the best.
    let mut best_direction: Best = None;
    let directions: Vec<_> = fibonacci(options.directions, up, -0.05)
        .into_iter()
        .map(|d| (d, None))
        .collect();
    consider(&mut best_direction, &directions);
    if let Some((_, coarse, _)) = best_direction {
        let spacing = (4.0 / options.directions as f32).sqrt();
        let near: Vec<_> = fibonacci(options.directions * 4, up, -0.05)
            .into_iter()
            .filter(|d| d.dot(coarse) > (2.0 * spacing).cos())
            .map(|d| (d, None))
            .collect();
        consider(&mut best_direction, &near);
    }
    // The best position: searched more coarsely (each distance would cost as much as the whole
    // directional search otherwise), then refined by a pattern search, since a position has
    // three coordinates to refine: steps along both tangents and the distance, made finer
    // whenever none improves, get there in far fewer scores than a dense grid.
    let point_directions = options.directions / POINT_DIRECTION_DIVISOR;
    let mut best_point: Best = None;
    let positions: Vec<_> = fibonacci(point_directions, up, -0.05)
        .into_iter()
        .flat_map(|d| point_distances.map(|r| (d, Some(r))))
        .collect();
    consider(&mut best_point, &positions);
    let mut step = (4.0 / point_directions as f32).sqrt();
    let mut factor = 1.25f32;
    for _ in 0..POINT_REFINE_MAX_ROUNDS {
        if step <= POINT_REFINE_STOP_RAD {
            break;
        }
        let Some((score, d, Some(r))) = best_point.filter(|b| b.0.is_finite()) else {
            break;
        };
        let (tx, ty) = tangents(d);
        let (sin, cos) = step.sin_cos();
        let steps: Vec<_> = [
            (d * cos + tx * sin, r),
            (d * cos - tx * sin, r),
            (d * cos + ty * sin, r),
            (d * cos - ty * sin, r),
            (d, (r * factor).min(max_distance)),
            (d, (r / factor).max(min_distance)),
        ]
        .into_iter()
        .filter(|(nd, _)| nd.dot(up) >= -0.05)
        .map(|(nd, nr)| (nd.normalize(), Some(nr)))
        .collect();
        consider(&mut best_point, &steps);
        if best_point.is_some_and(|(b, _, _)| b >= score) {
            step *= 0.5;
            factor = factor.sqrt();
        }
    }
    // A position has one parameter more than a direction, enough to fit a local gradient (a
    // sunlit patch, a wall's falloff) with a weak nearby light: it must explain the photo better
    // than the best direction by the margin a light must bring over none.
    let best = match (best_direction, best_point) {
        (Some(d), Some(p)) if p.0 < d.0 * (1.0 - options.min_improvement as f64) => Some(p),
        (d, _) => d,
    };
    let Some((_, direction, distance)) = best else {
        return Ok(nothing_found(
            fallback(samples.len(), fixed_lights),
            baseline_score,
        ));
    };
    // Angular size (seen from the insertion point): a cone of directions for a few widths; the
    // softest that does not explain the photo worse wins.
    let (tx, ty) = tangents(direction);
    // Infinite until a width is supported: when none is, nothing was found (see `candidate`).
    let mut best_size = (
        Scored {
            score: f64::INFINITY,
            residual: f64::INFINITY,
            disagreement: 0.0,
            column: Vec::new(),
        },
        0.0f32,
    );
    let sizes = [0.5f32, 4.0, 12.0, 25.0];
    let scored_sizes: Vec<Scored> = sizes
        .par_iter()
        .map(|&size_deg| {
            let r = (size_deg / 2.0).to_radians();
            let mut cone = vec![direction];
            for k in 0..8 {
                let a = k as f32 * std::f32::consts::TAU / 8.0;
                let rr = r * if k % 2 == 0 { 1.0 } else { 0.6 };
                cone.push((direction + (tx * a.cos() + ty * a.sin()) * rr.tan()).normalize());
            }
            score_candidate(if size_deg < 1.0 { &cone[..1] } else { &cone }, distance)
        })
        .collect();
    for (scored, size_deg) in scored_sizes.into_iter().zip(sizes) {
        if scored.score < best_size.0.score - 1e-4 {
            best_size = (scored, size_deg);
        }
    }
    let (
        Scored {
            score,
            residual: fitted_residual,
            disagreement,
            column,
        },
        size_deg,
    ) = best_size;
    // A light that leaves half of the shading unexplained is not an inference, whatever its
    // shadows earn.
    let keep_fitted = score < baseline_score * (1.0 - options.min_improvement as f64)
        && score < MAX_EXPLAINED_RESIDUAL
        && fitted_residual < MAX_EXPLAINED_RESIDUAL;
    let fitted_light = |intensity: [f32; 3]| {
        let mut l = match distance {
            None => Light::directional((-direction).to_array(), size_deg, intensity),
            Some(r) => Light::point(
                (centre + direction * r).to_array(),
                2.0 * r * (size_deg / 2.0).to_radians().tan(),
                intensity,
            ),
        };
        l.confidence = (1.0 - score / baseline_score.max(1e-9)).clamp(0.05, 1.0) as f32;
        l
    };
    // The light this search found, if any: a direction where no candidate lights enough of the
    // photo to be judged (every score infinite) is no finding, and a second search beside it
    // would only repeat the first.
    let candidate = || {
        score.is_finite().then(|| Candidate {
            light: fitted_light([1.0; 3]),
            score,
        })
    };
    let not_kept = |fit: LightFit| OneFit {
        fit,
        baseline: baseline_score,
        candidate: candidate(),
        kept: false,
        fixed_kept: vec![false; fixed_lights.len()],
        centre,
    };
    if !keep_fitted && fixed_lights.is_empty() {
        return Ok(not_kept(fallback(samples.len(), fixed_lights)));
    }

    // Magnitudes come from the luminance fit. Colour: with the luminance fit's region albedos
    // held, each channel's intensities are a linear least-squares solve (grey-world: the albedos'
    // colour is taken as neutral), kept within a factor of two of grey, since the colour of a
    // poorly explained photo can wander off and a light's colour rarely lies outside that range.
    // The fitted out-of-view light stays neutral: it and the ambient term light the same few
    // regions, so their colours trade off against each other and against the regions' colour,
    // and a room with a brown floor hands the light the floor's colour (in the built-in `room`
    // seen from above, red twice blue).
    let g = build(keep_fitted.then_some(&column));
    let lum_fit = trimmed(&g, &luma, &regions, n_regions, options.albedo);
    // In-view sources that the fit gives no light explain nothing (a sunlit patch taken for a
    // lamp) and are not handed on as lights. With no fitted light either, nothing was inferred,
    // which is what the fallback is for.
    // Judged in f32, as the intensities are handed on: a positive f64 that rounds to zero
    // lights nothing either.
    let lights_nothing = |x: f64| {
        let x = x as f32;
        x.is_nan() || x <= 0.0
    };
    if !keep_fitted
        && lum_fit.x[..fixed_lights.len()]
            .iter()
            .all(|x| lights_nothing(*x))
    {
        return Ok(not_kept(fallback(samples.len(), &[])));
    }
    let (_, rho) = projected(&g, &luma, &regions, n_regions, &lum_fit.x);
    let channel: Vec<Vec<f64>> = (0..3)
        .map(|k| {
            let m = g.columns;
            let mut a = vec![vec![0.0f64; m + 1]; m];
            for ((row, s), r) in g.rows().zip(&samples).zip(&regions) {
                for i in 0..m {
                    let gi = row[i] as f64 * rho[*r];
                    for j in 0..m {
                        a[i][j] += gi * row[j] as f64 * rho[*r];
                    }
                    a[i][m] += gi * s.rgb[k] as f64;
                }
            }
            // The fitted lights (this search's, and those of an earlier one among the fixed
            // lights) are held at their luminance in every channel (neutral), so the other
            // lights' and the ambient term's colours are solved under the lights that are
            // handed out, not under tinted ones that are then discarded.
            let held = fixed_lights.len() - held_neutral..fixed_lights.len() + keep_fitted as usize;
            for f in held {
                let x = lum_fit.x[f].max(0.0);
                for (i, row) in a.iter_mut().enumerate() {
                    if i != f {
                        row[m] -= row[f] * x;
                        row[f] = 0.0;
                    }
                }
                a[f] = vec![0.0; m + 1];
                a[f][f] = 1.0;
                a[f][m] = x;
            }
            solve(a)
        })
        .collect();
    let value = |j: usize| -> [f32; 3] {
        let rgb = [0, 1, 2].map(|k| channel[k][j].max(0.0) as f32);
        let l = lum_fit.x[j].max(0.0) as f32;
        let y = luminance(rgb);
        if y <= 1e-12 {
            return [l; 3];
        }
        let c = rgb.map(|v| (v / y).clamp(0.5, 2.0));
        let cy = luminance(c).max(1e-6);
        c.map(|v| v / cy * l)
    };
    let pi = std::f32::consts::PI;
    let mut lights = Vec::new();
    for (j, l) in fixed_lights.iter().enumerate() {
        if lights_nothing(lum_fit.x[j]) {
            continue;
        }
        // E_j = I / π for a light at a position (diffuse radiance = ρ/π · I cosθ / r²).
        lights.push(Light {
            intensity: value(j).map(|v| v * pi),
            ..*l
        });
    }
    if keep_fitted {
        lights.push(fitted_light(
            [lum_fit.x[fixed_lights.len()].max(0.0) as f32 * pi; 3],
        ));
    }
    let ambient = value(g.columns - 1);
    // Main light: the most irradiance at the insertion point (unoccluded, facing it).
    let main = lights
        .iter()
        .copied()
        .max_by(|a, b| irradiance_at(a, centre).total_cmp(&irradiance_at(b, centre)))
        .unwrap_or_else(|| fallback(0, fixed_lights).main);
    let residual = if keep_fitted {
        alternate(&g, &luma, &regions, n_regions, options.albedo).residual
    } else {
        baseline.residual
    };
    let fit = LightFit {
        main,
        ambient,
        lights,
        fallback_used: false,
        residual: residual as f32,
        shadow_disagreement: if keep_fitted {
            disagreement as f32
        } else {
            0.0
        },
        samples: samples.len(),
    };
    Ok(OneFit {
        fit,
        baseline: baseline_score,
        candidate: candidate(),
        kept: keep_fitted,
        fixed_kept: lum_fit.x[..fixed_lights.len()]
            .iter()
            .map(|x| !lights_nothing(*x))
            .collect(),
        centre,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::shadow_mask::continuity_regions;

    /// Ray-traced truth of a small room: floor y = −1, back wall z = −6, left wall x = −3 and a
    /// box on the floor, lit by a directional light towards `to_light` plus ambient `ambient`.
    /// The planes are infinite: a light behind a wall (x < 0 or z < 0) would be blocked by it.
    struct Room {
        photo: Raster<[f32; 3]>,
        depth: Raster<f32>,
        normals: Raster<[f32; 3]>,
        shadow: Raster<f32>,
        camera: Camera,
    }

    fn hit_box(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> Option<(f32, Vec3)> {
        let inv = d.recip();
        let (t1, t2) = ((lo - o) * inv, (hi - o) * inv);
        let (tmin, tmax) = (t1.min(t2), t1.max(t2));
        let t0 = tmin.max_element();
        if t0 > 1e-4 && t0 <= tmax.min_element() {
            let n = if t0 == tmin.x {
                Vec3::X * -d.x.signum()
            } else if t0 == tmin.y {
                Vec3::Y * -d.y.signum()
            } else {
                Vec3::Z * -d.z.signum()
            };
            Some((t0, n))
        } else {
            None
        }
    }

    #[test]
    fn stereo_depth_noise_does_not_shadow_a_floor_but_the_box_still_does() {
        // The room's exact depth with correlated inverse-depth noise of σ_w = 0.01 /m (3 % of
        // depth at 3 m, errors correlated over ~7 px, like a matcher's).
        let to_light = Vec3::new(1.0, 0.5, 0.1).normalize();
        let r = room(to_light, 0.2, 2.0);
        let (w, h) = (r.depth.width(), r.depth.height());
        let noise = crate::mesh::local_fit::tests::correlated_noise_field(w, h, 3, 0.01, 11);
        let noisy = Raster::from_fn(w, h, |x, y| {
            let z = *r.depth.get(x, y);
            1.0 / (1.0 / z + noise.get(x, y))
        });
        let sigma_w = depth_noise(&noisy);
        assert!((0.005..0.02).contains(&sigma_w), "measured σ_w {sigma_w}");
        let agreement = |sigma_w: f32| {
            let occluders = Occluders {
                depth: &noisy,
                camera: &r.camera,
                sigma_w,
            };
            let (mut lit, mut lit_seen, mut shadowed, mut shadowed_seen) = (0, 0, 0, 0);
            for y in (0..h).step_by(2) {
                for x in (0..w).step_by(2) {
                    let n = Vec3::from(*r.normals.get(x, y));
                    let z = *noisy.get(x, y);
                    let Some(p) = r.camera.unproject(x as f32 + 0.5, y as f32 + 0.5, z) else {
                        continue;
                    };
                    if n != Vec3::Y {
                        continue;
                    }
                    let visible = visible(&occluders, p, n, to_light, 6.0, None);
                    if *r.shadow.get(x, y) > 0.5 {
                        shadowed += 1;
                        shadowed_seen += usize::from(!visible);
                    } else {
                        lit += 1;
                        lit_seen += usize::from(visible);
                    }
                }
            }
            assert!(lit > 500 && shadowed > 50, "{lit} lit, {shadowed} shadowed");
            (
                lit_seen as f32 / lit as f32,
                shadowed_seen as f32 / shadowed as f32,
            )
        };
        // One σ of margin: 96 % of the lit floor is seen lit (88 % without the margin) and half
        // of the box's shadow is still found (79 % without).
        let (lit_ok, shadow_ok) = agreement(sigma_w);
        assert!(lit_ok > 0.93, "lit floor seen lit: {lit_ok}");
        assert!(shadow_ok > 0.45, "box shadow seen: {shadow_ok}");
        // Without the noise margin the same floor shadows itself.
        let (lit_without, _) = agreement(0.0);
        assert!(lit_without < lit_ok - 0.05, "{lit_without} vs {lit_ok}");
    }

    #[test]
    fn a_lamp_seen_in_the_photo_does_not_shadow_its_own_light() {
        // A wall at 4 m and, in front of it, a bulb of radius 0.1 m centred at (0, 0.5, −3): its
        // front surface is in the depth map, and the light sits behind it, at its centre.
        let camera = Camera::from_focal(100.0, 80, 60).unwrap();
        let centre = Vec3::new(0.0, 0.5, -3.0);
        let depth = Raster::from_fn(80, 60, |x, y| {
            let d = camera.ray_direction(x as f32 + 0.5, y as f32 + 0.5);
            let (b, c) = (d.dot(centre), centre.length_squared() - 0.01);
            let disc = b * b - d.length_squared() * c;
            let t = if disc >= 0.0 {
                (b - disc.sqrt()) / d.length_squared()
            } else {
                -4.0 / d.z
            };
            -(d * t).z
        });
        let occluders = Occluders {
            depth: &depth,
            camera: &camera,
            sigma_w: 0.0,
        };
        let bulb = Light {
            kind: LightKind::Point,
            position: centre.to_array(),
            direction: [0.0, -1.0, 0.0],
            size: 0.2,
            intensity: [1.0; 3],
            confidence: 1.0,
        };
        // A floor point in view straight below the bulb: nothing lies between them but the
        // bulb's own surface.
        let floor = Sample {
            p: Vec3::new(0.0, -0.5, -3.0),
            n: Vec3::Y,
            rgb: [0.5; 3],
            region: 0,
            mask: 0.0,
        };
        let shade = terms(&bulb, &floor, &occluders, 10.0).0;
        assert!((shade - 1.0).abs() < 1e-4, "{shade}");
        // The wall around and behind the bulb sees it past the bulb's own front surface.
        for k in 0..8 {
            let a = k as f32 * std::f32::consts::TAU / 8.0;
            let wall = Sample {
                p: Vec3::new(0.4 * a.cos(), 0.5 + 0.4 * a.sin(), -4.0),
                n: Vec3::Z,
                ..floor
            };
            assert!(terms(&bulb, &wall, &occluders, 10.0).0 > 0.0, "{}", wall.p);
        }
        // A point behind the wall is still shadowed by it.
        let behind = Sample {
            p: Vec3::new(0.0, 0.3, -4.5),
            n: Vec3::Z,
            ..floor
        };
        assert_eq!(terms(&bulb, &behind, &occluders, 10.0).0, 0.0);
    }

    #[test]
    fn the_predicted_shadow_is_the_hidden_part_of_the_light() {
        let sample = |mask: f32| Sample {
            p: Vec3::new(0.0, -1.0, -3.0),
            n: Vec3::Y,
            rgb: [0.5; 3],
            region: 0,
            mask,
        };
        // A wide cone whose directions' cosines average 0.8 on a sample that sees all of it: no
        // predicted shadow, whatever the cosine of the cone's centre (1 here).
        let samples = [sample(0.0), sample(1.0), sample(0.0)];
        // (lit, unoccluded, facing cosine) per sample.
        let lit_open = [(0.8, 0.8, 1.0), (0.0, 0.8, 1.0), (0.4, 0.8, 1.0)];
        let close = |c: ShadowComparison, disagreement: f64, against_none: f64| {
            assert!(
                (c.disagreement - disagreement).abs() < 1e-6
                    && (c.against_none - against_none).abs() < 1e-6,
                "{c:?}: expected {disagreement}, {against_none}"
            );
        };
        // Agreement on the first two; the third is half hidden against an unshadowed mask.
        // Against predicting no shadow, the second earns 1 and the third costs 0.5.
        let c = compare_shadows(&samples, &lit_open, &[(0.0, 0.0); 3], 1.0, |_| Vec3::Y);
        close(c, 0.5 / 3.0, -0.5 / 3.0);
        // Samples facing away from the light do not count.
        let c = compare_shadows(&samples, &lit_open, &[(0.0, 0.0); 3], 1.0, |_| -Vec3::Y);
        close(c, 0.0, 0.0);
        // Another light as strong, seen by every sample: the candidate's shadow is half as dark
        // (second: 0.5 against 1, as far from the mask as no shadow would be; third: 0.25
        // against 0).
        let others = [(0.8, 0.8); 3];
        let c = compare_shadows(&samples, &lit_open, &others, 1.0, |_| Vec3::Y);
        close(c, 0.75 / 3.0, -0.25 / 3.0);
        // Facing away from the candidate, the samples are judged by the other light alone, which
        // casts no shadow on them: the mask's shadow is missed, which costs nothing against
        // predicting none.
        let c = compare_shadows(&samples, &lit_open, &others, 1.0, |_| -Vec3::Y);
        close(c, 1.0 / 3.0, 0.0);
    }

    /// What lights [`room_lit`]: a sun towards a direction, or a bulb at a position.
    #[derive(Clone, Copy)]
    enum Lit {
        Sun(Vec3),
        Bulb(Vec3),
    }

    fn room(to_light: Vec3, ambient: f32, irradiance: f32) -> Room {
        room_lit(Lit::Sun(to_light), ambient, irradiance)
    }

    /// The room of [`Room`] lit by `lit` of `strength` (a sun's irradiance, a bulb's intensity).
    fn room_lit(lit: Lit, ambient: f32, strength: f32) -> Room {
        room_lit_by(&[(lit, strength)], ambient)
    }

    /// The room of [`Room`] lit by several lights, each with its strength. Its shadow mask is the
    /// part of the direct light hidden from each surface.
    fn room_lit_by(lights: &[(Lit, f32)], ambient: f32) -> Room {
        let (w, h) = (160, 120);
        let camera = Camera::from_focal(120.0, w, h).unwrap();
        let (lo, hi) = (Vec3::new(-0.5, -1.0, -4.3), Vec3::new(0.3, -0.2, -3.5));
        let (lo2, hi2) = (Vec3::new(0.8, -1.0, -3.2), Vec3::new(1.2, -0.6, -2.8));
        let trace = |o: Vec3, d: Vec3| -> Option<(f32, Vec3, f32)> {
            let mut best: Option<(f32, Vec3, f32)> = None;
            let mut consider = |t: f32, n: Vec3, albedo: f32| {
                if t > 1e-4 && best.is_none_or(|b| t < b.0) {
                    best = Some((t, n, albedo));
                }
            };
            if d.y < 0.0 {
                consider((-1.0 - o.y) / d.y, Vec3::Y, 0.6);
            }
            if d.z < 0.0 {
                consider((-6.0 - o.z) / d.z, Vec3::Z, 0.45);
            }
            if d.x < 0.0 {
                consider((-3.0 - o.x) / d.x, Vec3::X, 0.5);
            }
            if let Some((t, n)) = hit_box(o, d, lo, hi) {
                consider(t, n, 0.3);
            }
            if let Some((t, n)) = hit_box(o, d, lo2, hi2) {
                consider(t, n, 0.7);
            }
            best
        };
        let mut photo = Raster::filled(w as usize, h as usize, [0.0f32; 3]);
        let mut depth = Raster::filled(w as usize, h as usize, f32::NAN);
        let mut normals = Raster::filled(w as usize, h as usize, [0.0f32; 3]);
        let mut shadow = Raster::filled(w as usize, h as usize, 0.0f32);
        for y in 0..h as usize {
            for x in 0..w as usize {
                let d = camera.ray_direction(x as f32 + 0.5, y as f32 + 0.5);
                let Some((t, n, albedo)) = trace(Vec3::ZERO, d) else {
                    continue;
                };
                let p = d * t;
                let texture = 0.85 + 0.15 * ((p.x * 7.0).sin() * (p.z * 5.0).cos()).abs();
                let (mut e, mut open) = (0.0, 0.0);
                for (lit, strength) in lights {
                    let (l, dist, falloff) = match *lit {
                        Lit::Sun(to_light) => (to_light.normalize(), f32::INFINITY, 1.0),
                        Lit::Bulb(at) => {
                            let r = at.distance(p);
                            ((at - p) / r, r, 1.0 / (r * r))
                        }
                    };
                    let unoccluded = strength * falloff * n.dot(l).max(0.0);
                    open += unoccluded;
                    if trace(p + n * 1e-3, l).is_none_or(|(t, _, _)| t >= dist) {
                        e += unoccluded;
                    }
                }
                let v =
                    albedo * texture / std::f32::consts::PI * (e + std::f32::consts::PI * ambient);
                *photo.get_mut(x, y) = [v, v * 0.95, v * 0.9];
                *depth.get_mut(x, y) = -p.z;
                *normals.get_mut(x, y) = n.to_array();
                *shadow.get_mut(x, y) = if open > 0.0 { 1.0 - e / open } else { 0.0 };
            }
        }
        Room {
            photo,
            depth,
            normals,
            shadow,
            camera,
        }
    }

    fn inputs<'a>(
        r: &'a Room,
        regions: &'a Raster<u32>,
        mask: Option<&'a Raster<f32>>,
    ) -> FitInputs<'a> {
        FitInputs {
            photo: &r.photo,
            depth: &r.depth,
            normals: &r.normals,
            regions,
            shadow_mask: mask,
            camera: &r.camera,
            up: [0.0, 1.0, 0.0],
        }
    }

    /// The default fit of `r` with its true shadows as the mask and no in-view lights.
    fn fit_with_mask(r: &Room) -> LightFit {
        let regions = continuity_regions(&r.depth, Some(&r.normals), 0.05, 20.0, 30).unwrap();
        fit_lights(
            &inputs(r, &regions, Some(&r.shadow)),
            &[],
            &Default::default(),
        )
        .unwrap()
    }

    #[test]
    fn finds_the_direction_of_an_out_of_view_sun() {
        for to_light in [Vec3::new(0.6, 1.0, 0.4), Vec3::new(0.25, 1.0, 0.8)] {
            let fit = fit_with_mask(&room(to_light, 0.15, 2.0));
            assert!(!fit.fallback_used);
            assert_eq!(fit.main.kind, LightKind::Directional, "{fit:?}");
            let found = -Vec3::from(fit.main.direction);
            let error = found.angle_between(to_light.normalize()).to_degrees();
            // The target for a light out of view is 20°; behind the camera, shadows fall
            // behind their casters and are partly hidden, so allow 15° here.
            assert!(error < 15.0, "{to_light}: found {found}, {error}°");
            // Both a sun and an ambient term are found (their ratio is not yet accurate: see the
            // report in docs/lights-eval.md).
            assert!(luminance(fit.main.intensity) > 0.0 && luminance(fit.ambient) > 0.0);
            assert!(fit.residual < 0.1, "{}", fit.residual);
        }
    }

    #[test]
    fn the_fit_does_not_depend_on_the_number_of_threads() {
        // Candidates are scored in parallel and the first of equal scores wins: one thread and
        // several must give the same lights to the bit. Two suns, so that the pair's searches
        // (which reuse the first search's terms across threads) run too.
        let r = room_lit_by(
            &[
                (Lit::Sun(Vec3::new(0.6, 1.0, 0.4)), 2.0),
                (Lit::Sun(Vec3::new(-0.5, 1.0, 0.6)), 1.4),
            ],
            0.1,
        );
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| fit_with_mask(&r))
        };
        let one = on(1);
        assert!(!one.fallback_used, "{one:?}");
        for threads in [3, 8] {
            assert_eq!(on(threads), one, "{threads} threads");
        }
    }

    #[test]
    fn the_shadows_of_a_second_light_do_not_hide_the_first() {
        // Two suns out of view, both casting the boxes' shadows; the mask holds both (each as
        // dark as its sun's share). The fit models one light: the stronger sun explains its own
        // shadows and misses the other's, which ambient light alone misses too. When the
        // candidate was charged for the shadows it missed and ambient light alone was not, the
        // fit fell back to the light above.
        let (strong, weak) = (Vec3::new(0.6, 1.0, 0.4), Vec3::new(-0.5, 1.0, 0.6));
        let r = room_lit_by(&[(Lit::Sun(strong), 2.0), (Lit::Sun(weak), 1.4)], 0.1);
        let fit = fit_with_mask(&r);
        assert!(!fit.fallback_used, "{fit:?}");
        let found = -Vec3::from(fit.main.direction);
        let error = found.angle_between(strong.normalize()).to_degrees();
        assert!(error < 20.0, "found {found}, {error}°");
    }

    #[test]
    fn region_sums_give_the_projected_residual_along_each_line() {
        // The intensity search's shortcut must give what the sample-by-sample residual gives,
        // including where a region's best albedo would be negative (clamped to 0).
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) as f64 / (1u64 << 31) as f64) as f32
        };
        let n_regions = 5;
        let g = Design {
            values: (0..400).flat_map(|_| [next(), next() * 0.5, 1.0]).collect(),
            columns: 3,
        };
        let regions: Vec<usize> = (0..400).map(|i| i % n_regions).collect();
        let y: Vec<f32> = g
            .rows()
            .zip(&regions)
            .map(|(row, &r)| {
                // Region 4 is lit the wrong way round: its best albedo is negative.
                let shade = 2.0 * row[0] + row[1] + 0.3;
                if r == 4 {
                    1.0 - shade
                } else {
                    0.2 * (r + 1) as f32 * shade + 0.05 * next()
                }
            })
            .collect();
        let sums = RegionSums::new(&g, &y, &regions, n_regions);
        for x in [
            [1.0, 0.0, 1.0],
            [2.0, 1.0, 0.3],
            [0.0, 0.0, 1.0],
            [5.0, 0.1, 0.0],
        ] {
            // Along each coordinate's line through `x`, at `x` itself and away from it.
            for j in 0..3 {
                let line = sums.along(&x, j);
                for t in [x[j], 0.0, 0.7, 3.0] {
                    let mut at = x;
                    at[j] = t;
                    let direct = projected(&g, &y, &regions, n_regions, &at).0;
                    let shortcut = line.residual(t);
                    assert!(
                        (direct - shortcut).abs() <= 1e-9 * direct.max(1.0),
                        "{at:?}, line {j}: {direct} against {shortcut}"
                    );
                }
            }
        }
    }

    #[test]
    fn finds_a_bulb_and_a_sun_both_out_of_view() {
        // A bulb above the frame on the left and a fainter sun from behind the camera on the
        // right, both casting the boxes' shadows. One light alone is the bulb; beside it the
        // second search finds the sun, and the pair explains the room better by more than the
        // margin, so both are handed on. With one light at most, the sun is missing.
        let bulb = Vec3::new(-1.0, 1.4, -2.0);
        let to_sun = Vec3::new(0.6, 1.0, 0.4);
        let r = room_lit_by(&[(Lit::Bulb(bulb), 12.0), (Lit::Sun(to_sun), 1.0)], 0.15);
        let regions = continuity_regions(&r.depth, Some(&r.normals), 0.05, 20.0, 30).unwrap();
        let fit_at_most = |max_out_of_view| {
            let options = FitOptions {
                max_out_of_view,
                ..Default::default()
            };
            fit_lights(&inputs(&r, &regions, Some(&r.shadow)), &[], &options).unwrap()
        };
        let found_bulb = |fit: &LightFit| {
            fit.lights.iter().any(|l| {
                l.kind == LightKind::Point
                    && Vec3::from(l.position).distance(bulb) < 0.1 * bulb.length()
            })
        };
        let found_sun = |fit: &LightFit| {
            fit.lights.iter().any(|l| {
                l.kind == LightKind::Directional
                    && (-Vec3::from(l.direction)).angle_between(to_sun.normalize())
                        < 20f32.to_radians()
            })
        };
        let pair = fit_at_most(2);
        assert!(!pair.fallback_used);
        assert_eq!(pair.lights.len(), 2, "{pair:?}");
        assert!(found_bulb(&pair) && found_sun(&pair), "{pair:?}");
        // Both fitted lights are handed on neutral, as a single fitted light is.
        for l in &pair.lights {
            let [r, g, b] = l.intensity;
            assert!(r == g && g == b && r > 0.0, "{l:?}");
        }
        let one = fit_at_most(1);
        assert_eq!(one.lights.len(), 1, "{one:?}");
        assert!(found_bulb(&one) && !found_sun(&one), "{one:?}");
        assert!(
            pair.residual < one.residual,
            "{} {}",
            pair.residual,
            one.residual
        );
    }

    #[test]
    fn a_faint_second_light_is_not_handed_on() {
        // Two suns, the second two thirds as strong as the first and from the other side: the
        // fit keeps one light there; a pair search that kept any improvement added a point
        // light far above the room at a hundredth of the sun's strength.
        let r = room_lit_by(
            &[
                (Lit::Sun(Vec3::new(-0.8, 1.0, 0.2)), 1.5),
                (Lit::Sun(Vec3::new(0.5, 1.0, 0.6)), 1.0),
            ],
            0.15,
        );
        let fit = fit_with_mask(&r);
        assert!(!fit.fallback_used);
        assert_eq!(fit.lights.len(), 1, "{fit:?}");
    }

    #[test]
    fn finds_the_position_of_an_out_of_view_bulb() {
        // Above the frame (30° up, the frame reaches 26.6°), 2.4 m above the floor: the floor
        // and the back wall fall off across their extent, which no sun explains.
        let at = Vec3::new(0.4, 1.4, -2.4);
        let fit = fit_with_mask(&room_lit(Lit::Bulb(at), 0.15, 12.0));
        assert!(!fit.fallback_used);
        assert_eq!(fit.main.kind, LightKind::Point, "{fit:?}");
        let error = Vec3::from(fit.main.position).distance(at);
        assert!(
            error < 0.1 * at.length(),
            "found {:?}, {error} m off",
            fit.main
        );
        fit.main.validate().unwrap();
        // The room's photo is tinted; the fitted light is neutral all the same.
        let [r, g, b] = fit.main.intensity;
        assert!(r == g && g == b, "{:?}", fit.main.intensity);
    }

    #[test]
    fn finds_an_out_of_view_sun_beside_a_lamp_in_view() {
        // A lamp in the frame (left, in front of the back wall) and a sun from above the frame,
        // both casting shadows of the boxes, the sun the stronger at the boxes. The mask holds
        // both lights' shadows (each as dark as its light's share); the candidate sun is judged
        // against it together with the lamp, and the lamp alone is judged against it too. When
        // each candidate was judged alone and the lamp not at all, the sun came out a quarter
        // of the lamp's strength and the lamp became the main light.
        let lamp = Vec3::new(-1.2, -0.3, -4.8);
        let to_sun = Vec3::new(0.6, 1.0, 0.4);
        let r = room_lit_by(&[(Lit::Bulb(lamp), 2.0), (Lit::Sun(to_sun), 2.0)], 0.1);
        let regions = continuity_regions(&r.depth, Some(&r.normals), 0.05, 20.0, 30).unwrap();
        let lamp_light = Light::point(lamp.to_array(), 0.1, [2.0; 3]);
        assert!(r.camera.project_to_pixel(lamp).is_some());
        // Also with a false source inside the nearer box, which lights no sample (the box's
        // faces turn away from it and hide it from everything else): it is fitted to no light
        // and not handed on (before, it stayed in `lights` at zero intensity whenever the
        // out-of-view light was kept).
        let false_source = Light::point([-0.1, -0.6, -3.9], 0.1, [2.0; 3]);
        for in_view in [vec![lamp_light], vec![lamp_light, false_source]] {
            let fit = fit_lights(
                &inputs(&r, &regions, Some(&r.shadow)),
                &in_view,
                &Default::default(),
            )
            .unwrap();
            assert!(!fit.fallback_used);
            assert_eq!(fit.lights.len(), 2, "{fit:?}");
            assert!(
                fit.lights.iter().all(|l| luminance(l.intensity) > 0.0),
                "{fit:?}"
            );
            assert_eq!(fit.lights[0].position, lamp_light.position, "{fit:?}");
            assert_eq!(fit.main.kind, LightKind::Directional, "{fit:?}");
            let error = (-Vec3::from(fit.main.direction))
                .angle_between(to_sun.normalize())
                .to_degrees();
            // The target for a light out of view (15° for the sun alone above).
            assert!(error < 20.0, "{fit:?}: {error}°");
        }
    }

    #[test]
    fn a_light_that_only_grazes_the_seen_surfaces_is_not_extrapolated() {
        // Only the floor is given to the fit, and the light comes in low (cos 0.15–0.19 on the
        // floor): only intensity × cos is measurable. Without the support rule the fit kept a
        // light of 16.9 (0.2° above the horizon) for a true 2.0.
        for to_light in [Vec3::new(0.3, 0.2, 1.0), Vec3::new(1.0, 0.15, 0.2)] {
            let r = room(to_light, 0.15, 2.0);
            let regions = continuity_regions(&r.depth, Some(&r.normals), 0.05, 20.0, 30).unwrap();
            let floor = Raster::from_fn(regions.width(), regions.height(), |x, y| {
                if *r.normals.get(x, y) == [0.0, 1.0, 0.0] {
                    *regions.get(x, y)
                } else {
                    NO_REGION
                }
            });
            let fit = fit_lights(
                &inputs(&r, &floor, Some(&r.shadow)),
                &[],
                &Default::default(),
            )
            .unwrap();
            // Either nothing is inferred, or a light near the true one and no more than twice
            // as bright (a direction steep enough to be supported explains the floor as well).
            // Supported directions rise at least 14.5° above the floor (cos ≥ 0.25), the true
            // ones 10.8° and 8.4°, so a kept light is 4–6° off before any error of its own; the
            // fit keeps one 10.1° off, at half the true intensity, for the second light.
            assert!(luminance(fit.main.intensity) < 4.0, "{to_light}: {fit:?}");
            if !fit.fallback_used {
                let error = (-Vec3::from(fit.main.direction))
                    .angle_between(to_light.normalize())
                    .to_degrees();
                assert!(error < 12.0, "{to_light}: {error}° {fit:?}");
            }
        }
    }

    #[test]
    fn a_photo_of_a_ceiling_alone_hands_on_its_lamp_and_searches_once() {
        // Only a ceiling in view, lit by a bulb hanging below it: every candidate above the
        // horizon reaches the ceiling from behind, so none can be judged. The search finds
        // nothing (before, the unsupported best direction came back as a candidate, with the
        // largest finite score, and two more searches were run beside it), and the bulb alone
        // is handed on.
        let (w, h) = (96usize, 72usize);
        let camera = Camera::from_focal(60.0, w as u32, h as u32).unwrap();
        let bulb_at = Vec3::new(0.2, 0.6, -3.0);
        let mut photo = Raster::filled(w, h, [0.0f32; 3]);
        let mut depth = Raster::filled(w, h, f32::NAN);
        let mut normals = Raster::filled(w, h, [0.0f32; 3]);
        for y in 0..h {
            for x in 0..w {
                let d = camera.ray_direction(x as f32 + 0.5, y as f32 + 0.5);
                if d.y <= 0.05 {
                    continue;
                }
                let p = d * (1.0 / d.y);
                let r = bulb_at.distance(p);
                let cos = (-Vec3::Y).dot((bulb_at - p) / r).max(0.0);
                let v = 0.5 * (0.2 + 3.0 * cos / (r * r));
                *photo.get_mut(x, y) = [v; 3];
                *depth.get_mut(x, y) = -p.z;
                *normals.get_mut(x, y) = [0.0, -1.0, 0.0];
            }
        }
        let r = Room {
            photo,
            depth,
            normals,
            shadow: Raster::filled(w, h, 0.0f32),
            camera,
        };
        let regions = continuity_regions(&r.depth, Some(&r.normals), 0.05, 20.0, 30).unwrap();
        let bulb = Light::point(bulb_at.to_array(), 0.05, [1.0; 3]);
        let one = fit_beside(
            &inputs(&r, &regions, None),
            &[bulb],
            0,
            &Default::default(),
            &SearchCache::default(),
        )
        .unwrap();
        assert!(
            one.candidate.is_none(),
            "{:?}",
            one.candidate.map(|c| c.score)
        );
        let fit = fit_lights(&inputs(&r, &regions, None), &[bulb], &Default::default()).unwrap();
        assert!(!fit.fallback_used, "{fit:?}");
        assert_eq!(fit.lights.len(), 1, "{fit:?}");
        assert_eq!(fit.lights[0].position, bulb.position);
        assert!(luminance(fit.lights[0].intensity) > 0.0, "{fit:?}");
    }

    #[test]
    fn a_flat_ambient_photo_falls_back_to_a_light_above() {
        // Ambient only: no direction explains anything better.
        let r = room(Vec3::Y, 0.3, 0.0);
        let regions = continuity_regions(&r.depth, Some(&r.normals), 0.05, 20.0, 30).unwrap();
        let fit = fit_lights(&inputs(&r, &regions, None), &[], &Default::default()).unwrap();
        assert!(fit.fallback_used);
        assert!(Vec3::from(fit.main.direction).abs_diff_eq(-Vec3::Y, 1e-5));
        fit.main.validate().unwrap();
    }

    #[test]
    fn an_in_view_source_that_lights_nothing_does_not_stand_for_an_inference() {
        // The ambient-only room with a false source (a sunlit patch taken for a lamp) under the
        // floor, where no sample sees it: its fitted intensity is zero and no out-of-view light
        // explains anything, so nothing was inferred. (Before, the zero-intensity source became
        // the main light and the fallback was not used.)
        let r = room(Vec3::Y, 0.3, 0.0);
        let regions = continuity_regions(&r.depth, Some(&r.normals), 0.05, 20.0, 30).unwrap();
        let false_source = [Light::point([0.0, -1.5, -4.0], 0.1, [2.0; 3])];
        let fit = fit_lights(
            &inputs(&r, &regions, None),
            &false_source,
            &Default::default(),
        )
        .unwrap();
        assert!(fit.fallback_used, "{fit:?}");
        assert!(luminance(fit.main.intensity) > 0.0, "{fit:?}");
        // The false source is not handed on as a light; a real lamp that lights the room is
        // (`finds_an_out_of_view_sun_beside_a_lamp_in_view`).
        assert_eq!(fit.lights, vec![fit.main], "{fit:?}");
    }

    #[test]
    fn extreme_input_gives_a_finite_fallback() {
        let camera = Camera::from_focal(10.0, 8, 6).unwrap();
        let black = Raster::filled(8, 6, [0.0f32; 3]);
        let depth = Raster::filled(8, 6, f32::NAN);
        let normals = Raster::filled(8, 6, [0.0f32; 3]);
        let regions = Raster::filled(8, 6, NO_REGION);
        let i = FitInputs {
            photo: &black,
            depth: &depth,
            normals: &normals,
            regions: &regions,
            shadow_mask: None,
            camera: &camera,
            up: [0.0, 1.0, 0.0],
        };
        let fit = fit_lights(&i, &[], &Default::default()).unwrap();
        assert!(fit.fallback_used);
        fit.main.validate().unwrap();
        assert!(fit.ambient.iter().all(|v| v.is_finite()));
        let bad = FitInputs { up: [0.0; 3], ..i };
        assert!(fit_lights(&bad, &[], &Default::default())
            .unwrap_err()
            .to_string()
            .contains("up"));
        let short = Raster::filled(7, 6, f32::NAN);
        let bad = FitInputs { depth: &short, ..i };
        assert!(fit_lights(&bad, &[], &Default::default())
            .unwrap_err()
            .to_string()
            .contains("depth"));
    }
}
