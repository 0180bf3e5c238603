//! The composite through the C ABI: `plx_scene_render`.

use std::mem::{offset_of, size_of};

use super::boundary::{invalid, null_argument, CallError};
use super::image_io::plx_image_out;
use super::scene::{plx_scene, with_scene};
use crate::error::Status;

/// `plx_render_options::shading` values.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum plx_shading_mode {
    /// glTF 2.0 metallic-roughness (default).
    Pbr = 0,
    /// The thesis' modified Blinn-Phong (eq. 3.27–3.30).
    Thesis = 1,
}

/// `plx_render_options::shadows` values.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum plx_shadow_mode {
    /// The thesis' exponential shadow maps with contact shadows (default).
    ThesisEsm = 0,
    /// Exponential variance shadow maps.
    Evsm = 1,
    /// Percentage-closer soft shadows (penumbra grows with the light's size).
    Pcss = 2,
    /// No shadows.
    Off = 3,
}

/// How the composite is rendered. Initialise with `plx_render_options_init`, then change fields.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_render_options {
    /// `sizeof(plx_render_options)` as the caller compiled it.
    pub size: usize,
    /// A `plx_shading_mode` value.
    pub shading: u32,
    /// A `plx_shadow_mode` value.
    pub shadows: u32,
    /// Shadow-map edge in texels, 512–4096 (default 1024; reduced to fit the device).
    pub shadow_map_size: u32,
    /// Shadow filter radius in texels, 0–8 (default 2).
    pub filter_radius: u32,
    /// Nonzero: anti-alias the artefacts' edges with 4× MSAA where the device supports it.
    pub msaa: u32,
}

/// Fills `options` with the defaults and its `size`.
///
/// # Safety
/// `options` is NULL or points to a writable `plx_render_options`.
#[no_mangle]
pub unsafe extern "C" fn plx_render_options_init(options: *mut plx_render_options) -> Status {
    super::boundary::guard(&super::handle::GLOBAL_ERROR, || {
        if options.is_null() {
            return Err(null_argument("options"));
        }
        *options = plx_render_options {
            size: size_of::<plx_render_options>(),
            shading: plx_shading_mode::Pbr as u32,
            shadows: plx_shadow_mode::ThesisEsm as u32,
            shadow_map_size: 1024,
            filter_radius: 2,
            msaa: 1,
        };
        Ok(())
    })
}

/// The fields of the caller's struct version, as raw words (absent ones are `None`).
unsafe fn read_words(options: *const plx_render_options) -> Result<[Option<u32>; 5], CallError> {
    let size = std::ptr::read_unaligned(options.cast::<usize>());
    if size < size_of::<usize>() {
        return Err(invalid(format!(
            "options.size is {size}: set it with plx_render_options_init"
        )));
    }
    let base = options.cast::<u8>();
    let word = |offset: usize| -> Option<u32> {
        (size >= offset + 4).then(|| std::ptr::read_unaligned(base.add(offset).cast::<u32>()))
    };
    Ok([
        word(offset_of!(plx_render_options, shading)),
        word(offset_of!(plx_render_options, shadows)),
        word(offset_of!(plx_render_options, shadow_map_size)),
        word(offset_of!(plx_render_options, filter_radius)),
        word(offset_of!(plx_render_options, msaa)),
    ])
}

/// Renders the composite: the photo with the scene's artefacts lit by its lights (the host's or
/// the estimated ones), hidden behind the photo's own geometry, casting shadows onto it. Writes
/// it into `out` (any `plx_pixel_format`, the photo's size, any stride; 8-bit formats as sRGB,
/// alpha 1) and, when `mask_out` is not NULL, the artefacts' coverage in [0, 1] into it (same
/// size; every channel the coverage). Without artefacts the composite is the photo and nothing
/// else is computed (no stereo, mesh, lights or GPU). Moving an artefact re-renders without
/// recomputing depth, mesh or lights; the report (`plx_scene_report`) shows each decision.
/// Errors: `NULL_ARGUMENT`; `INVALID_ARGUMENT` (options out of range, bad output format or
/// stride); `SIZE_MISMATCH` (an output of another size than the photo); `NOT_AVAILABLE` without a
/// stereo pair; `GPU` without a usable adapter (the scene stays usable); `UNSUPPORTED` in a build
/// without the `gpu` and `gltf` features. Nothing is written on error.
///
/// # Safety
/// `scene` is a live scene; `options` is NULL (defaults) or valid for `options->size` bytes;
/// `out` and `mask_out` (nullable) are valid `plx_image_out`s.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_render(
    scene: *mut plx_scene,
    options: *const plx_render_options,
    out: *const plx_image_out,
    mask_out: *const plx_image_out,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let words = if options.is_null() {
            [None; 5]
        } else {
            read_words(options)?
        };
        render_into(scene, words, out, mask_out)
    })
}

#[cfg(all(feature = "gpu", feature = "gltf"))]
unsafe fn render_into(
    scene: &mut crate::scene::Scene,
    words: [Option<u32>; 5],
    out: *const plx_image_out,
    mask_out: *const plx_image_out,
) -> Result<(), CallError> {
    use super::image_io::write_linear;
    use crate::render::{RenderOptions, ShadingMode, ShadowMode};

    let mut options = RenderOptions::default();
    if let Some(v) = words[0] {
        options.shading = match v {
            0 => ShadingMode::Pbr,
            1 => ShadingMode::Thesis,
            other => {
                return Err(invalid(format!(
                    "unknown shading mode {other} (0 pbr, 1 thesis)"
                )))
            }
        };
    }
    if let Some(v) = words[1] {
        options.shadows = match v {
            0 => ShadowMode::ThesisEsm,
            1 => ShadowMode::Evsm,
            2 => ShadowMode::Pcss,
            3 => ShadowMode::Off,
            other => {
                return Err(invalid(format!(
                    "unknown shadow mode {other} (0 thesis ESM, 1 EVSM, 2 PCSS, 3 off)"
                )))
            }
        };
    }
    if let Some(v) = words[2] {
        options.shadow_map_size = v;
    }
    if let Some(v) = words[3] {
        options.filter_radius = v;
    }
    if let Some(v) = words[4] {
        options.msaa = v != 0;
    }
    let (w, h) = scene.photo_size().ok_or_else(|| {
        CallError::from(crate::Error::NotAvailable(
            "no photo: set a stereo pair (plx_scene_set_stereo_pair) or a photo (plx_scene_set_photo)"
                .into(),
        ))
    })?;
    // Check the outputs before the work, so a wrong buffer fails fast.
    check_out(out, "out", w, h)?;
    if !mask_out.is_null() {
        check_out(mask_out, "mask_out", w, h)?;
    }
    let composite = scene.render(&options)?;
    let c = &composite.composite;
    write_linear(out, "out", w, h, |x, y| {
        let p = c.get(x, y);
        [p[0], p[1], p[2], 1.0]
    })?;
    if !mask_out.is_null() {
        let m = &composite.mask;
        write_linear(mask_out, "mask_out", w, h, |x, y| {
            let v = *m.get(x, y);
            [v, v, v, 1.0]
        })?;
    }
    Ok(())
}

#[cfg(all(feature = "gpu", feature = "gltf"))]
unsafe fn check_out(
    out: *const plx_image_out,
    name: &str,
    w: u32,
    h: u32,
) -> Result<(), CallError> {
    let d = &*out;
    if (d.width, d.height) != (w, h) {
        return Err(CallError {
            status: Status::SizeMismatch,
            message: format!(
                "{name} is {}x{} but the photo is {w}x{h}",
                d.width, d.height
            ),
        });
    }
    Ok(())
}

#[cfg(not(all(feature = "gpu", feature = "gltf")))]
unsafe fn render_into(
    _scene: &mut crate::scene::Scene,
    _words: [Option<u32>; 5],
    _out: *const plx_image_out,
    _mask_out: *const plx_image_out,
) -> Result<(), CallError> {
    Err(crate::Error::Unsupported(
        "this build of Parallax has no renderer (features `gpu` and `gltf`)".into(),
    )
    .into())
}
