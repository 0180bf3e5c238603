//! Stereo depth (thesis §3.2.1): from a rectified pair to a dense disparity map of the left view
//! with a per-pixel confidence, then depth.
//!
//! Pipeline of [`match_pair`], each step an option of [`StereoOptions`]:
//! 1. grey levels (sRGB code values, 0–255); optionally undo a vertical offset and small rotation
//!    of the right view ([`rectify`]);
//! 2. optionally match a half-size pair first and narrow each pixel's search ([`pyramid`]); from
//!    its disparities, measure and undo the pair's residual vertical misalignment
//!    ([`alignment`]);
//! 3. matching costs, census ([`census`]) or SAD blocks ([`sad`]), computed row by row;
//! 4. aggregation: semi-global matching on 8 or 4 paths ([`sgm`]) or the thesis' scanline
//!    dynamic programming ([`dp`]);
//! 5. winner-takes-all, `U_p` confidence (eq. 3.5), sub-pixel, uniqueness, L/R check
//!    ([`refine`]), speckles ([`speckle`]);
//! 6. hole filling and edge-aware smoothing ([`fill`]).
//!
//! Disparity follows DESIGN.md: `d = x_left − x_right ≥ 0` in pixels, NaN where there is no estimate
//! (only with `fill = false`). Depth is `Z = f·B/(d + doffs)` ([`depth_map`]). Without a
//! calibration, [`assumed_calibration`] gives depth **up to scale**: a 60° horizontal field of view
//! and a baseline of 1, so depth comes out in baselines.
//!
//! Threads: the two SGM sweeps run in parallel (rayon), and every row-wise step is parallel over
//! rows. Hot loops are compiled twice and chosen at run time for AVX2 ([`simd`]).

pub mod alignment;
pub mod buffer;
pub mod census;
pub mod cost;
pub mod dp;
pub mod fill;
pub mod metrics;
pub mod noise;
pub mod options;
pub mod preview;
pub mod pyramid;
pub mod rectify;
pub mod refine;
pub mod sad;
pub mod sgm;
pub mod simd;
pub mod speckle;

use std::time::Instant;

use rayon::prelude::*;

pub use options::{Aggregation, CostKind, Preset, StereoOptions, Subpixel};

use crate::camera::StereoCalibration;
use crate::error::{Error, Result};
use crate::image::{rec709_luma, ImageView, PixelFormat, Raster};
use cost::CostRows;
use refine::{DecideOptions, Decision, PixelState};

/// Horizontal field of view assumed by [`assumed_calibration`], degrees.
pub const ASSUMED_HORIZONTAL_FOV_DEG: f64 = 60.0;

/// The result of [`match_pair`].
#[derive(Debug, Clone)]
pub struct Disparity {
    /// Disparity of each left-view pixel in pixels (`x_left − x_right`); NaN = no estimate, which
    /// only happens with `fill = false`.
    pub disparity: Raster<f32>,
    /// Confidence in [0, 1] from the uncertainty term `U_p` (eq. 3.5):
    /// `1 / (1 + U_p / (paths · P1))`; filled pixels get 0, and so do pixels with nothing to
    /// match (every disparity costs the same; [`StereoStats::textureless_fraction`]).
    pub confidence: Raster<f32>,
    /// Timings and counts.
    pub stats: StereoStats,
}

/// What [`match_pair`] did and what it cost.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct StereoStats {
    /// Wall-clock milliseconds of each sub-stage in order: `stereo.prepare`, `stereo.rectify`,
    /// `stereo.coarse`, the half-size level's own steps as `stereo.coarse.cost`, … (parts of
    /// `stereo.coarse`), `stereo.align` (measuring and undoing the residual misalignment),
    /// `stereo.cost` (census transform; per-row costs are computed inside aggregation and
    /// counted there), `stereo.noise` (the matches' cost floor, with `noise_adaptive_penalties`),
    /// `stereo.aggregate`, `stereo.decide`, `stereo.textureless`, `stereo.speckle`,
    /// `stereo.refine`, `stereo.fill`, `stereo.smooth`. Steps that did not run are absent.
    pub timings: Vec<(String, f64)>,
    /// Total matching time, milliseconds (decoded images in, disparity out).
    pub total_ms: f64,
    /// Fraction of pixels without an estimate before filling (0–1).
    pub invalid_fraction: f32,
    /// Fraction of pixels with nothing to match (0–1): every disparity searched costs the same,
    /// as on a textureless stretch wider than the search (or one clipped to black or white).
    /// Their disparity is what aggregation carried in, with confidence 0
    /// (`refine::mark_textureless`).
    pub textureless_fraction: f32,
    /// Peak bytes of the matcher's own working buffers (input images not counted).
    pub peak_working_bytes: u64,
    /// Vertical offset (pixels) and rotation (degrees) undone in the right view, when estimated.
    pub misalignment: Option<(f32, f32)>,
    /// The residual vertical misalignment undone in the right view (`refine_alignment`), when
    /// one large enough to matter was found.
    pub residual_alignment: Option<alignment::VerticalResidual>,
    /// Median census cost (0–255) of the pair's matches at the half-size level's disparities,
    /// when measured (`noise_adaptive_penalties`): 24–49 on clean photographs, more on noisy ones.
    pub match_cost_floor: Option<f32>,
    /// Factor applied to P1 and P2 for this pair (1 = as given; see [`noise::penalty_scale`]).
    pub penalty_scale: f32,
}

impl StereoStats {
    fn time<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        crate::trace::time_part(&mut self.timings, name, f)
    }
}

/// Matches a rectified stereo pair: the disparity of every pixel of `left`. A one-off match; to
/// match a stream of frames, keep a [`StereoMatcher`].
///
/// # Errors
/// `SizeMismatch` when the views differ in size; `InvalidArgument` for an image narrower or lower
/// than 2 pixels or an option out of range (`max_disparity` 0 or ≥ width, …).
pub fn match_pair(
    left: &ImageView,
    right: &ImageView,
    options: &StereoOptions,
) -> Result<Disparity> {
    // A workspace that keeps nothing: each buffer is freed as soon as its step is done, which
    // keeps the peak within the matcher's memory bound (tests/stereo_large.rs).
    match_views(left, right, options, &mut buffer::Workspace::default())
}

/// A matcher that keeps its large working buffers from one match to the next, as a host
/// matching the frames of a stereo camera wants: the aggregated costs, the stored cost volume
/// and the census transforms (shared by the half-size and the full-size level) are not
/// allocated again for a pair no larger than the last, and the kernel does not zero fresh pages
/// for them, some 20 MB of writes per 0.35 MP frame. The smaller per-pixel buffers (grey
/// images, disparity, fill and smoothing) are still allocated per match. Results are the same
/// as [`match_pair`]'s, bit for bit.
///
/// Between matches it holds [`StereoMatcher::retained_bytes`]: 3 bytes per pixel and disparity
/// searched by the level that searches the most (2 without a stored cost volume) and 18 bytes
/// per pixel, at the largest size matched so far; [`StereoMatcher::release`] frees them.
#[derive(Debug)]
pub struct StereoMatcher {
    workspace: buffer::Workspace,
}

impl Default for StereoMatcher {
    fn default() -> Self {
        StereoMatcher {
            workspace: buffer::Workspace::keeping(),
        }
    }
}

impl StereoMatcher {
    /// A matcher holding no memory yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Bytes kept between matches.
    pub fn retained_bytes(&self) -> usize {
        self.workspace.bytes()
    }

    /// Frees the memory kept between matches.
    pub fn release(&mut self) {
        self.workspace = buffer::Workspace::keeping();
    }

    /// As [`match_pair`], in this matcher's memory.
    ///
    /// # Errors
    /// As [`match_pair`].
    pub fn match_pair(
        &mut self,
        left: &ImageView,
        right: &ImageView,
        options: &StereoOptions,
    ) -> Result<Disparity> {
        match_views(left, right, options, &mut self.workspace)
    }
}

fn match_views(
    left: &ImageView,
    right: &ImageView,
    options: &StereoOptions,
    workspace: &mut buffer::Workspace,
) -> Result<Disparity> {
    if (left.width(), left.height()) != (right.width(), right.height()) {
        return Err(Error::SizeMismatch(format!(
            "stereo views differ in size: left {}x{}, right {}x{}",
            left.width(),
            left.height(),
            right.width(),
            right.height()
        )));
    }
    if left.width() < 2 || left.height() < 2 {
        return Err(Error::invalid(format!(
            "stereo matching needs images of at least 2x2 pixels, got {}x{}",
            left.width(),
            left.height()
        )));
    }
    options.validate(left.width())?;
    let start = Instant::now();
    let mut stats = StereoStats::default();
    let (l, mut r) = stats.time("stereo.prepare", || {
        rayon::join(|| grey(left), || grey(right))
    });
    if options.correct_misalignment {
        let (est, warped) = stats.time("stereo.rectify", || {
            let est = rectify::estimate_misalignment(&l, &r, options.max_disparity as usize);
            let warped = rectify::apply_misalignment(&r, &est);
            (est, warped)
        });
        r = warped;
        stats.misalignment = Some((est.dy, est.angle_deg));
    }
    let full_search_cells = l.width() * l.height() * (options.max_disparity as usize + 1);
    let out = match_grey(&l, &r, options, full_search_cells, &mut stats, workspace)?;
    stats.total_ms = start.elapsed().as_secs_f64() * 1e3;
    Ok(Disparity {
        disparity: out.0,
        confidence: out.1,
        stats,
    })
}

/// Grey levels 0–255 of the encoded values (what block matching wants; see `ImageView::to_luma`).
fn grey(view: &ImageView) -> Raster<u8> {
    // 8-bit colour: the same arithmetic as `to_luma`, with the channels' places fixed per format
    // and rows in parallel, rather than a format match and a float image in between.
    let layout = match view.format() {
        PixelFormat::Gray8 => Some((1, [0, 0, 0])),
        PixelFormat::Rgb8 => Some((3, [0, 1, 2])),
        PixelFormat::Rgba8 => Some((4, [0, 1, 2])),
        PixelFormat::Bgra8 => Some((4, [2, 1, 0])),
        _ => None,
    };
    let to_u8 = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    let Some((bytes, [r, g, b])) = layout else {
        return view.to_luma().map(|&v| to_u8(v));
    };
    let (w, h) = (view.width() as usize, view.height() as usize);
    // Each channel's term of the luma sum per code value (the luma of that channel alone),
    // looked up instead of computed: `rec709_luma`'s products exactly, added in its order, so
    // the grey levels are the same.
    const S: f32 = 1.0 / 255.0;
    let term = |channel: usize| -> [f32; 256] {
        std::array::from_fn(|v| {
            let mut rgb = [0.0; 3];
            rgb[channel] = v as f32 * S;
            rec709_luma(rgb)
        })
    };
    let [tr, tg, tb] = [0, 1, 2].map(term);
    let mut out = vec![0u8; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        for (o, px) in out.iter_mut().zip(view.row(y as u32).chunks_exact(bytes)) {
            *o = to_u8(tr[px[r] as usize] + tg[px[g] as usize] + tb[px[b] as usize]);
        }
    });
    Raster::from_vec(w, h, out)
}

/// The whole pipeline on grey images; returns (disparity, confidence).
/// `full_search_cells`: pixels × disparities of the full-size search, whose 2 bytes each bound the
/// working memory (a coarse level uses its parent's). The large buffers are made in `workspace`'s
/// memory and given back to it.
pub(crate) fn match_grey(
    l: &Raster<u8>,
    r: &Raster<u8>,
    o: &StereoOptions,
    full_search_cells: usize,
    stats: &mut StereoStats,
    workspace: &mut buffer::Workspace,
) -> Result<(Raster<f32>, Raster<f32>)> {
    let (w, h) = (l.width(), l.height());
    let n = w * h;
    let levels = o.max_disparity as usize + 1;

    // A half-size match (SGM only) needs the half-size pair wide enough to hold its half range.
    // Coarse-to-fine uses it when the window is narrower than the range; the alignment step
    // measures the misalignment from it.
    let coarse_max = o.max_disparity.div_ceil(2).max(1);
    let half_size_match = o.aggregation != Aggregation::ScanlineDp
        && (w.div_ceil(2) as u32) > coarse_max + 1
        && h >= 4;
    let use_coarse = half_size_match && o.coarse_levels > 0 && (o.coarse_window as usize) < levels;
    let wants_alignment = half_size_match && o.refine_alignment;
    let (bases, k, r, coarse) = if use_coarse || wants_alignment {
        let start = Instant::now();
        let (cl, cr) = rayon::join(|| pyramid::reduce(l), || pyramid::reduce(r));
        // The coarse level only centres each pixel's window, and the window's margin absorbs
        // its errors: 4 paths and no uniqueness or speckle checks measured as accurate as the
        // whole pipeline there (docs/stereo-eval.md). The L/R check stays, so that occlusions
        // are filled with the background and the finer level searches around it.
        let coarse_opts = StereoOptions {
            max_disparity: coarse_max,
            coarse_levels: o.coarse_levels.saturating_sub(1),
            aggregation: Aggregation::Sgm4,
            uniqueness: 0,
            speckle_size: 0,
            fill: true,
            smoothing_passes: 0,
            local_refinement_radius: 0,
            refine_alignment: false,
            ..o.clone()
        };
        let mut coarse_stats = StereoStats::default();
        let (coarse, _) = match_grey(
            &cl,
            &cr,
            &coarse_opts,
            full_search_cells,
            &mut coarse_stats,
            workspace,
        )?;
        let (bases, k) = if use_coarse {
            let k = o.coarse_window as usize;
            let bases = pyramid::window_bases(&coarse, w, h, k, o.max_disparity as usize);
            (Some(bases), k)
        } else {
            (None, levels)
        };
        stats.peak_working_bytes = coarse_stats.peak_working_bytes;
        stats
            .timings
            .push(("stereo.coarse".into(), start.elapsed().as_secs_f64() * 1e3));
        // The coarse level's own stages follow, as `stereo.coarse.cost`, … (inside the above).
        for (name, ms) in coarse_stats.timings {
            let sub = name.strip_prefix("stereo.").unwrap_or(&name);
            stats.timings.push((format!("stereo.coarse.{sub}"), ms));
        }
        let aligned = if wants_alignment {
            stats.time("stereo.align", || align_residual(l, r, &coarse))
        } else {
            None
        };
        if let Some((m, warped)) = aligned {
            stats.residual_alignment = Some(m);
            (bases, k, std::borrow::Cow::Owned(warped), Some(coarse))
        } else {
            (bases, k, std::borrow::Cow::Borrowed(r), Some(coarse))
        }
    } else {
        (None, levels, std::borrow::Cow::Borrowed(r), None)
    };
    let r: &Raster<u8> = &r;

    let cost = stats.time("stereo.cost", || Costs::new(l, r, o, &mut workspace.census));
    // A noisy pair's matches cost more, closer to unrelated pixels: the penalties grow to keep
    // their balance with the data term (census, measured at the half-size level's disparities).
    let penalty_scale = match (&coarse, o.noise_adaptive_penalties, o.cost) {
        (Some(coarse), true, CostKind::Census) => {
            let floor = stats.time("stereo.noise", || {
                noise::match_cost_floor(cost.rows(), coarse)
            });
            stats.match_cost_floor = floor;
            floor.map_or(1.0, noise::penalty_scale)
        }
        _ => 1.0,
    };
    stats.penalty_scale = penalty_scale;
    let scaled = |p: u16| (p as f32 * penalty_scale).round().min(u16::MAX as f32) as u16;
    let cost_bytes = match o.cost {
        CostKind::Census => 16 * n,
        CostKind::Sad => 0,
    };
    let fixed = 2 * n + cost_bytes + bases.as_ref().map_or(0, |b| b.len() * 2);

    let mut decision = match o.aggregation {
        Aggregation::Sgm8 | Aggregation::Sgm4 => {
            let paths = if o.aggregation == Aggregation::Sgm8 {
                8
            } else {
                4
            };
            let pen = sgm::Penalties::new(scaled(o.p1), scaled(o.p2), o.p2_gradient_scale, paths);
            // Costs are computed once for both sweeps, in a stored volume (1 byte a pixel and
            // disparity searched), when the whole of this step's memory still fits the matcher's
            // bound, 2 bytes per pixel and disparity of the full-size range plus 64 MiB: with a
            // narrow coarse-to-fine window, and at a coarse level.
            let peak = |store_costs: bool| {
                fixed
                    + sgm::working_bytes(w, h, k, store_costs)
                    + 9 * n
                    + 12 * w * rayon::current_num_threads()
            };
            let store_costs = peak(true) <= 2 * full_search_cells + (64 << 20);
            let agg = stats.time("stereo.aggregate", || {
                sgm::aggregate(
                    cost.rows(),
                    l,
                    bases.as_deref(),
                    k,
                    paths,
                    &pen,
                    store_costs,
                    workspace,
                )
            });
            let opts = DecideOptions {
                subpixel: o.subpixel,
                uniqueness: o.uniqueness,
                lr_max_diff: o.lr_max_diff,
                confidence_unit: pen.p1 as f32,
            };
            stats.peak_working_bytes = stats.peak_working_bytes.max(peak(store_costs) as u64);
            let decision = stats.time("stereo.decide", || {
                refine::decide(&agg, bases.as_deref(), &opts)
            });
            agg.recycle(workspace);
            decision
        }
        Aggregation::ScanlineDp => {
            let (mut disparity, confidence) = stats.time("stereo.aggregate", || {
                dp::scanline_dp(cost.rows(), k, o.dp_penalty, o.subpixel)
            });
            let mut state = vec![PixelState::Valid; n];
            if let Some(tol) = o.lr_max_diff {
                let mirror =
                    |img: &Raster<u8>| Raster::from_fn(w, h, |x, y| *img.get(w - 1 - x, y));
                let (ml, mr) = (mirror(r), mirror(l));
                let right = stats.time("stereo.aggregate_right", || {
                    let c = Costs::new(&ml, &mr, o, &mut Default::default());
                    dp::scanline_dp(c.rows(), k, o.dp_penalty, o.subpixel).0
                });
                let right = Raster::from_fn(w, h, |x, y| *right.get(w - 1 - x, y));
                stats.time("stereo.decide", || {
                    dp::cross_check(&mut disparity, &right, tol, &mut state)
                });
            }
            let per_row = w * k * 6;
            let peak = 2 * fixed + 4 * 3 * n + per_row * rayon::current_num_threads();
            stats.peak_working_bytes = stats.peak_working_bytes.max(peak as u64);
            Decision {
                disparity,
                state,
                confidence,
            }
        }
    };
    let textureless = stats.time("stereo.textureless", || {
        refine::mark_textureless(cost.rows(), bases.as_deref(), k, &mut decision.confidence)
    });
    stats.textureless_fraction = textureless as f32 / n as f32;
    cost.recycle(workspace);

    if o.speckle_size > 0 {
        stats.time("stereo.speckle", || {
            refine::remove_speckles(
                &mut decision.disparity,
                &mut decision.state,
                o.speckle_size as usize,
                o.speckle_range,
            )
        });
    }
    if o.local_refinement_radius > 0 {
        stats.time("stereo.refine", || {
            refine::refine_locally(
                &mut decision.disparity,
                l,
                r,
                o.local_refinement_radius as usize,
                2,
            )
        });
    }
    let holes = decision
        .disparity
        .pixels()
        .par_iter()
        .filter(|v| v.is_nan())
        .count();
    stats.invalid_fraction = holes as f32 / n as f32;
    let Decision {
        mut disparity,
        state,
        mut confidence,
    } = decision;
    confidence
        .pixels_mut()
        .par_iter_mut()
        .zip(disparity.pixels().par_iter())
        .for_each(|(c, d)| {
            if d.is_nan() {
                *c = 0.0;
            }
        });
    if o.fill {
        stats.time("stereo.fill", || fill::fill_holes(&mut disparity, &state));
        if o.smoothing_passes > 0 {
            let so = fill::SmoothOptions {
                passes: o.smoothing_passes,
                sigma_intensity: 12.0,
                max_jump: 1.5,
                edge_weight: 0.2,
            };
            stats.time("stereo.smooth", || {
                fill::smooth(&mut disparity, &confidence, l, &so)
            });
        }
    }
    // Sub-pixel and smoothing stay within the searched range; clamp against rounding anyway.
    let top = o.max_disparity as f32;
    disparity.pixels_mut().par_iter_mut().for_each(|d| {
        if !d.is_nan() {
            *d = d.clamp(0.0, top);
        }
    });
    Ok((disparity, confidence))
}

/// Smallest residual misalignment worth resampling the right view for, pixels at the worst
/// corner: resampling softens the view a little, and on Middlebury's exactly rectified pairs the
/// estimate stays within 0.05 px at the centre and 0.2 px at a corner (docs/stereo-eval.md).
const MIN_ALIGNMENT_CORRECTION_PX: f32 = 0.1;

/// The residual misalignment of `r` measured from the half-size disparities, and `r` with it
/// undone, when it is large enough to matter.
fn align_residual(
    l: &Raster<u8>,
    r: &Raster<u8>,
    coarse: &Raster<f32>,
) -> Option<(alignment::VerticalResidual, Raster<u8>)> {
    let m = alignment::estimate_residual(l, r, coarse, 2)?;
    if m.largest(l.width(), l.height()) < MIN_ALIGNMENT_CORRECTION_PX {
        return None;
    }
    Some((m, m.apply(r)))
}

/// The matching cost the options ask for.
enum Costs<'a> {
    Census(census::CensusCost),
    Sad(sad::SadCost<'a>),
}

impl<'a> Costs<'a> {
    /// Census costs are transformed in the memory taken from `spare_census` (left, right).
    fn new(
        l: &'a Raster<u8>,
        r: &'a Raster<u8>,
        o: &StereoOptions,
        spare_census: &mut [Vec<u64>; 2],
    ) -> Self {
        match o.cost {
            CostKind::Census => Costs::Census(census::CensusCost::in_buffers(
                l,
                r,
                o.census_radius.0 as usize,
                o.census_radius.1 as usize,
                std::mem::take(spare_census),
            )),
            CostKind::Sad => Costs::Sad(sad::SadCost::new(l, r, o.sad_radius as usize)),
        }
    }

    fn rows(&self) -> &dyn CostRows {
        match self {
            Costs::Census(c) => c,
            Costs::Sad(c) => c,
        }
    }

    /// Gives the census transforms' memory back to `workspace`.
    fn recycle(self, workspace: &mut buffer::Workspace) {
        if let Costs::Census(c) = self {
            workspace.give_back_census(c.into_buffers());
        }
    }
}

/// A calibration for a pair without one: focal length from a 60° horizontal field of view
/// ([`ASSUMED_HORIZONTAL_FOV_DEG`]), principal point at the centre and a baseline of 1 m, so
/// [`depth_map`] gives depth **up to scale**, in units of the (unknown) baseline.
pub fn assumed_calibration(width: u32, height: u32) -> Result<StereoCalibration> {
    let half = (ASSUMED_HORIZONTAL_FOV_DEG.to_radians() / 2.0).tan();
    StereoCalibration::from_focal_baseline(width as f64 / (2.0 * half), 1.0, width, height)
}

/// Depth in metres of every pixel, `Z = f·B/(d + doffs)`; NaN where the disparity is NaN or
/// `d + doffs ≤ 0` (infinitely far).
///
/// # Errors
/// `InvalidArgument` for a calibration with a non-finite or non-positive value.
pub fn depth_map(disparity: &Raster<f32>, calibration: &StereoCalibration) -> Result<Raster<f32>> {
    calibration.validate()?;
    Ok(disparity.map(|&d| calibration.depth_from_disparity(d)))
}

#[cfg(test)]
mod tests;
