//! `parallax depth`: disparity, depth and confidence of a rectified stereo pair.

use std::path::PathBuf;

use parallax::camera::StereoCalibration;
use parallax::image::{Image, ImageLimits, Raster};
use parallax::stereo::{self, Preset, StereoOptions};
use parallax::trace::{StageStatus, Trace};
use parallax::Error;

use crate::common::CommonArgs;

/// Arguments of `parallax depth`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Left view (PNG or JPEG).
    #[arg(long, value_name = "PNG")]
    left: PathBuf,
    /// Right view, same size as the left.
    #[arg(long, value_name = "PNG")]
    right: PathBuf,
    /// Middlebury calib.txt: focal length, baseline, doffs and the disparity range (ndisp).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["focal", "baseline"])]
    calib: Option<PathBuf>,
    /// Focal length in pixels (with --baseline), when there is no calib.txt.
    #[arg(long, value_name = "PX", requires = "baseline")]
    focal: Option<f64>,
    /// Baseline in metres (with --focal).
    #[arg(long, value_name = "M", requires = "focal")]
    baseline: Option<f64>,
    /// Largest disparity searched, pixels (default: ndisp − 1 from --calib, else 64).
    #[arg(long, value_name = "N")]
    max_disparity: Option<u32>,
    /// Option preset: fast, balanced or quality.
    #[arg(long, default_value = "balanced", value_name = "P")]
    preset: String,
    /// Any matcher option on its own, over the preset: a JSON object of `StereoOptions` fields,
    /// inline or `@FILE` (for example `{"smoothing_passes": 2, "aggregation": "sgm4"}`). The
    /// flags below and --max-disparity take precedence.
    #[arg(long, value_name = "JSON|@FILE")]
    options: Option<String>,
    /// Keep pixels without an estimate as NaN (inf in the PFM) instead of filling them.
    #[arg(long)]
    no_fill: bool,
    /// Estimate and undo a vertical offset (±8 px) and small rotation (≤ 1°) of the right view.
    #[arg(long)]
    correct_misalignment: bool,
    /// Disparity of the left view, PFM (Middlebury: inf = no estimate).
    #[arg(long, value_name = "PFM")]
    out_disparity: PathBuf,
    /// Depth in metres, PFM. Without --calib or --focal/--baseline, depth is up to scale (60°
    /// horizontal field of view, baseline 1).
    #[arg(long, value_name = "PFM")]
    out_depth: Option<PathBuf>,
    /// Confidence in [0, 1], PFM.
    #[arg(long, value_name = "PFM")]
    out_confidence: Option<PathBuf>,
    /// Colour-mapped disparity, PNG.
    #[arg(long, value_name = "PNG")]
    out_preview: Option<PathBuf>,
    #[command(flatten)]
    common: CommonArgs,
}

/// Loads the pair, matches it and writes what was asked for.
pub fn run(args: Args) -> parallax::Result<()> {
    let mut trace = Trace::new();
    let limits = ImageLimits::default();
    let (left, right) = trace.time("load", "input files", |_| -> parallax::Result<_> {
        Ok((
            Image::load(&args.left, &limits)?,
            Image::load(&args.right, &limits)?,
        ))
    })?;
    let calibration = match (&args.calib, args.focal, args.baseline) {
        (Some(path), _, _) => Some(StereoCalibration::load_middlebury(path)?),
        (None, Some(f), Some(b)) => Some(StereoCalibration::from_focal_baseline(
            f,
            b,
            left.width(),
            left.height(),
        )?),
        _ => None,
    };
    let preset: Preset = args.preset.parse()?;
    let mut options = StereoOptions::preset(preset);
    if let Some(spec) = &args.options {
        options = crate::common::stereo_options(&options, spec)?;
    }
    options.max_disparity = args
        .max_disparity
        .or_else(|| {
            calibration
                .and_then(|c| c.max_disparity)
                .map(|n| n.saturating_sub(1).max(1))
        })
        .unwrap_or(64);
    if args.no_fill {
        options.fill = false;
    }
    if args.correct_misalignment {
        options.correct_misalignment = true;
    }

    let spinner = args.common.spinner("matching");
    let result = stereo::match_pair(&left.view(), &right.view(), &options);
    spinner.finish_and_clear();
    let result = result?;
    trace.record(
        "stereo",
        StageStatus::Computed,
        result.stats.total_ms,
        "stereo pair given",
    );
    let (w, h) = (result.disparity.width(), result.disparity.height());
    for (name, ms) in &result.stats.timings {
        let why = match (name.as_str(), &result.stats.residual_alignment) {
            ("stereo.align", Some(m)) => format!(
                "sub-stage of stereo: right view moved along its columns by up to {:.2} px \
                 (offset {:.3} px, {:.6} px per column, {:.6} px per row)",
                m.largest(w, h),
                m.offset,
                m.per_column,
                m.per_row
            ),
            ("stereo.align", None) => {
                "sub-stage of stereo: no residual misalignment worth undoing".to_string()
            }
            _ => "sub-stage of stereo".to_string(),
        };
        trace.record(name.clone(), StageStatus::Computed, *ms, why);
    }
    if let Some((dy, angle)) = result.stats.misalignment {
        trace.warn(format!(
            "right view corrected by a vertical offset of {dy:.2} px and a rotation of {angle:.3}°"
        ));
    }

    trace.time("write", "output files", |_| -> parallax::Result<()> {
        result.disparity.write_pfm(&args.out_disparity)?;
        if let Some(path) = &args.out_confidence {
            result.confidence.write_pfm(path)?;
        }
        if let Some(path) = &args.out_preview {
            stereo::preview::colorize(&result.disparity, options.max_disparity as f32)?
                .save_png(path)?;
        }
        Ok(())
    })?;
    if let Some(path) = &args.out_depth {
        let calib = match calibration {
            Some(c) => c,
            None => {
                trace.warn("no calibration: depth is up to scale (60° horizontal field of view, baseline 1)");
                stereo::assumed_calibration(left.width(), left.height())?
            }
        };
        let depth: Raster<f32> = trace.time("depth", "asked for --out-depth", |_| {
            stereo::depth_map(&result.disparity, &calib)
        })?;
        depth.write_pfm(path)?;
    }
    if !args.common.quiet {
        eprintln!(
            "parallax: {}x{} matched in {:.1} ms ({} preset, disparities 0..={}), {:.1} % without an estimate before filling, {:.1} % with nothing to match, {:.1} MB working memory",
            left.width(),
            left.height(),
            result.stats.total_ms,
            preset,
            options.max_disparity,
            result.stats.invalid_fraction * 100.0,
            result.stats.textureless_fraction * 100.0,
            result.stats.peak_working_bytes as f64 / (1024.0 * 1024.0)
        );
    }
    args.common.finish(&trace).map_err(|e: Error| e)
}
