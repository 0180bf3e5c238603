//! The stereo stage through the C ABI: options, and disparity / confidence / depth views.

use std::mem::{offset_of, size_of};

use super::boundary::{invalid, null_argument, CallError};
use super::scene::{plx_scene, with_scene};
use crate::error::Status;
use crate::image::Raster;
use crate::scene::Scene;
use crate::stereo::{Aggregation, CostKind, Preset, StereoOptions};

/// Presets of `plx_stereo_options::preset`.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum plx_stereo_preset {
    /// Census 5×5, 4-path SGM after a half-resolution pass, light smoothing; fastest.
    Fast = 0,
    /// Census 7×7, 4-path SGM after a half-resolution pass that also measures and undoes the
    /// pair's residual vertical misalignment; consistency checks, fill and edge-aware smoothing.
    Balanced = 1,
    /// Census 9×7, 8-path SGM with a wider window after the half-resolution pass and a local fit
    /// on the grey levels: nearly twice balanced's time, more precise below a pixel (default).
    Quality = 2,
}

impl From<Preset> for plx_stereo_preset {
    fn from(preset: Preset) -> Self {
        match preset {
            Preset::Fast => plx_stereo_preset::Fast,
            Preset::Balanced => plx_stereo_preset::Balanced,
            Preset::Quality => plx_stereo_preset::Quality,
        }
    }
}

/// Matching methods of `plx_stereo_options::method`.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum plx_stereo_method {
    /// The preset's own method.
    PresetDefault = 0,
    /// Census cost, semi-global matching along 8 paths.
    CensusSgm8 = 1,
    /// Census cost, semi-global matching along 4 paths.
    CensusSgm4 = 2,
    /// The thesis' method: SAD blocks and scanline dynamic programming.
    SadDp = 3,
}

/// Options of the stereo matcher. Initialise with `plx_stereo_options_init`, then change fields.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_stereo_options {
    /// `sizeof(plx_stereo_options)` as the caller compiled it.
    pub size: usize,
    /// A `plx_stereo_preset` value (default `PLX_STEREO_PRESET_QUALITY`, what a scene matches
    /// with when no options are set: its mesh, planes and placements need that precision).
    pub preset: u32,
    /// Largest disparity searched, pixels; 0 = from the calibration (`max_disparity`), else a
    /// quarter of the image width. Must be less than the image width.
    pub max_disparity: u32,
    /// A `plx_stereo_method` value (default `PLX_STEREO_METHOD_PRESET_DEFAULT`).
    pub method: u32,
    /// 1 = dense output (holes filled, the default); 0 = pixels without an estimate stay NaN.
    pub fill: u32,
    /// Half-resolution levels matched first to narrow the search; -1 = the preset's choice.
    pub coarse_levels: i32,
}

/// Fills `options` with the defaults and its `size`.
///
/// # Safety
/// `options` is NULL or points to a writable `plx_stereo_options`.
#[no_mangle]
pub unsafe extern "C" fn plx_stereo_options_init(options: *mut plx_stereo_options) -> Status {
    super::boundary::guard(&super::handle::GLOBAL_ERROR, || {
        if options.is_null() {
            return Err(null_argument("options"));
        }
        *options = plx_stereo_options {
            size: size_of::<plx_stereo_options>(),
            preset: plx_stereo_preset::from(Scene::DEFAULT_STEREO_PRESET) as u32,
            max_disparity: 0,
            method: plx_stereo_method::PresetDefault as u32,
            fill: 1,
            coarse_levels: -1,
        };
        Ok(())
    })
}

/// Reads the fields the caller's struct version has and turns them into [`StereoOptions`];
/// `max_disparity` 0 is returned as `None` (the scene's automatic choice).
unsafe fn read_options(
    options: *const plx_stereo_options,
) -> Result<(StereoOptions, Option<u32>), CallError> {
    let size = std::ptr::read(options.cast::<usize>());
    let base = options.cast::<u8>();
    let field = |offset: usize| -> Option<u32> {
        (size >= offset + 4).then(|| std::ptr::read_unaligned(base.add(offset).cast::<u32>()))
    };
    if size < size_of::<usize>() {
        return Err(invalid(format!(
            "options.size is {size}: set it with plx_stereo_options_init"
        )));
    }
    let scene_default = plx_stereo_preset::from(Scene::DEFAULT_STEREO_PRESET) as u32;
    let preset = match field(offset_of!(plx_stereo_options, preset)).unwrap_or(scene_default) {
        0 => Preset::Fast,
        1 => Preset::Balanced,
        2 => Preset::Quality,
        other => return Err(invalid(format!("options.preset: unknown preset {other}"))),
    };
    let mut out = StereoOptions::preset(preset);
    match field(offset_of!(plx_stereo_options, method)).unwrap_or(0) {
        0 => {}
        1 => (out.cost, out.aggregation) = (CostKind::Census, Aggregation::Sgm8),
        2 => (out.cost, out.aggregation) = (CostKind::Census, Aggregation::Sgm4),
        3 => {
            let thesis = StereoOptions::thesis();
            (out.cost, out.aggregation, out.subpixel) =
                (thesis.cost, thesis.aggregation, thesis.subpixel);
        }
        other => return Err(invalid(format!("options.method: unknown method {other}"))),
    }
    match field(offset_of!(plx_stereo_options, fill)).unwrap_or(1) {
        0 => out.fill = false,
        1 => out.fill = true,
        other => return Err(invalid(format!("options.fill must be 0 or 1, got {other}"))),
    }
    if let Some(levels) = field(offset_of!(plx_stereo_options, coarse_levels)) {
        match levels as i32 {
            -1 => {}
            l @ 0..=4 => out.coarse_levels = l as u32,
            other => {
                return Err(invalid(format!(
                    "options.coarse_levels must be -1 or 0–4, got {other}"
                )))
            }
        }
    }
    let max_disparity = field(offset_of!(plx_stereo_options, max_disparity)).filter(|d| *d > 0);
    Ok((out, max_disparity))
}

/// Sets the stereo matcher's options (NULL = back to the defaults). Errors: `INVALID_ARGUMENT`
/// for an unknown preset or method or a value out of range. On error the scene is unchanged.
///
/// # Safety
/// `scene` is a live scene; `options` is NULL or valid for `options->size` bytes.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_stereo_options(
    scene: *mut plx_scene,
    options: *const plx_stereo_options,
) -> Status {
    with_scene(scene, |scene| {
        if options.is_null() {
            scene.reset_stereo_options();
            return Ok(());
        }
        let (options, max_disparity) = read_options(options)?;
        scene.set_stereo_options_auto_range(options, max_disparity)?;
        Ok(())
    })
}

/// A borrowed grid of floats in library memory: `height` rows of `stride` bytes, each holding
/// `width` floats. Valid until the next call that changes the scene it came from.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_float_view {
    /// First value of the top row.
    pub data: *const f32,
    /// Values per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Bytes from one row to the next.
    pub stride: usize,
}

pub(crate) fn float_view(raster: &Raster<f32>) -> plx_float_view {
    plx_float_view {
        data: raster.pixels().as_ptr(),
        width: raster.width() as u32,
        height: raster.height() as u32,
        stride: raster.width() * size_of::<f32>(),
    }
}

unsafe fn write_view(out: *mut plx_float_view, raster: &Raster<f32>) {
    *out = float_view(raster);
}

/// The disparity of the left view in pixels (`x_left − x_right`); NaN where there is no estimate
/// (only with `fill = 0`). Runs the stereo matcher unless the pair and options are unchanged since
/// the last call. Errors: `NOT_AVAILABLE` without a stereo pair; `INVALID_ARGUMENT` when the
/// options do not fit the images (e.g. `max_disparity` ≥ width).
///
/// # Safety
/// `scene` is a live scene; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_disparity(
    scene: *mut plx_scene,
    out: *mut plx_float_view,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let d = scene.disparity()?;
        write_view(out, &d.disparity);
        Ok(())
    })
}

/// The matcher's confidence in [0, 1] per pixel (thesis eq. 3.5; filled pixels get 0, and so
/// do pixels with nothing to match, where every disparity costs the same). Same computation,
/// errors and lifetime as `plx_scene_disparity`.
///
/// # Safety
/// `scene` is a live scene; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_confidence(
    scene: *mut plx_scene,
    out: *mut plx_float_view,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let d = scene.disparity()?;
        write_view(out, &d.confidence);
        Ok(())
    })
}

/// Depth of the left view in metres, `Z = f·B/(d + doffs)`; NaN where unknown. Without a
/// calibration, depth is up to scale (60° field of view, baseline 1; the report warns). Same
/// errors and lifetime as `plx_scene_disparity`.
///
/// # Safety
/// `scene` is a live scene; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_depth(
    scene: *mut plx_scene,
    out: *mut plx_float_view,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let depth = scene.depth()?;
        write_view(out, &depth);
        Ok(())
    })
}
