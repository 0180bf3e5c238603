//! Images leaving the library into host memory (`plx_image_out`, any `plx_pixel_format`, any
//! stride), and images read from files for hosts without their own decoder.
//!
//! Every image product a function hands to the host goes through `write_linear`, so each one
//! offers every format and stride the same way: the renderer's composite follows this pattern.

use std::ffi::{c_char, CStr};

use super::boundary::{invalid, null_argument, CallError};
use super::image::pixel_format;
use super::scene::{plx_scene, with_scene};
use crate::error::{Error, Status};
use crate::image::{linear_to_srgb8, Image, PixelFormat};

/// An image in caller memory that Parallax fills: `height` rows of `stride` bytes starting at
/// `data`, each row `width` pixels of `format` (a `plx_pixel_format` value). 8-bit formats
/// receive sRGB-encoded colour, float formats linear colour (1.0 = the photo's white); grey
/// formats receive the luminance (Rec. 709). Bytes between the end of a row and the next stride
/// are left untouched, as is everything on failure.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_image_out {
    /// First byte of the top row.
    pub data: *mut u8,
    /// Pixels per row: must equal the product's width.
    pub width: u32,
    /// Rows: must equal the product's height.
    pub height: u32,
    /// Bytes from the start of one row to the next (≥ width × bytes per pixel).
    pub stride: usize,
    /// A `plx_pixel_format` value.
    pub format: u32,
}

/// Writes a `width × height` image given as linear RGBA per pixel into the host's `out`, in the
/// format and stride it asks for. Checks everything before the first byte is written.
///
/// # Safety
/// `out` is NULL or points to a `plx_image_out` whose `data` spans `stride × (height − 1) + row`
/// writable bytes.
pub(crate) unsafe fn write_linear(
    out: *const plx_image_out,
    name: &str,
    width: u32,
    height: u32,
    pixel: impl Fn(usize, usize) -> [f32; 4],
) -> Result<(), CallError> {
    if out.is_null() {
        return Err(null_argument(name));
    }
    let d = &*out;
    if d.data.is_null() {
        return Err(null_argument(&format!("{name}.data")));
    }
    let format = pixel_format(d.format).map_err(|e| invalid(format!("{name}: {}", e.message)))?;
    if (d.width, d.height) != (width, height) {
        return Err(CallError {
            status: Status::SizeMismatch,
            message: format!(
                "{name} is {}x{} but the image is {width}x{height}",
                d.width, d.height
            ),
        });
    }
    let bpp = format.bytes_per_pixel();
    let row = width as usize * bpp;
    if d.stride < row {
        return Err(invalid(format!(
            "{name}: stride {} bytes is shorter than a row of {width} {format:?} pixels ({row} bytes)",
            d.stride
        )));
    }
    let fits = d
        .stride
        .checked_mul(height as usize - 1)
        .and_then(|n| n.checked_add(row))
        .is_some_and(|n| n <= isize::MAX as usize);
    if !fits {
        return Err(invalid(format!(
            "{name}: {height} rows of stride {} overflow memory",
            d.stride
        )));
    }
    for y in 0..height as usize {
        let dst = std::slice::from_raw_parts_mut(d.data.add(y * d.stride), row);
        for (x, px) in dst.chunks_exact_mut(bpp).enumerate() {
            encode(format, pixel(x, y), px);
        }
    }
    Ok(())
}

/// One pixel, linear RGBA in, into `px` in `format`. Non-finite values are written as 0.
fn encode(format: PixelFormat, rgba: [f32; 4], px: &mut [u8]) {
    let [r, g, b, a] = rgba.map(|v| if v.is_finite() { v } else { 0.0 });
    let luma = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    let alpha8 = (a.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    let put = |px: &mut [u8], values: &[f32]| {
        for (chunk, v) in px.chunks_exact_mut(4).zip(values) {
            chunk.copy_from_slice(&v.to_ne_bytes());
        }
    };
    match format {
        PixelFormat::Gray8 => px[0] = linear_to_srgb8(luma),
        PixelFormat::Rgb8 => {
            px.copy_from_slice(&[linear_to_srgb8(r), linear_to_srgb8(g), linear_to_srgb8(b)])
        }
        PixelFormat::Rgba8 => px.copy_from_slice(&[
            linear_to_srgb8(r),
            linear_to_srgb8(g),
            linear_to_srgb8(b),
            alpha8,
        ]),
        PixelFormat::Bgra8 => px.copy_from_slice(&[
            linear_to_srgb8(b),
            linear_to_srgb8(g),
            linear_to_srgb8(r),
            alpha8,
        ]),
        PixelFormat::GrayF32 => put(px, &[luma]),
        PixelFormat::RgbF32 => put(px, &[r, g, b]),
        PixelFormat::RgbaF32 => put(px, &[r, g, b, a]),
        PixelFormat::RgbaF16 => {
            for (chunk, v) in px.chunks_exact_mut(2).zip([r, g, b, a]) {
                chunk.copy_from_slice(&half::f16::from_f32(v).to_ne_bytes());
            }
        }
    }
}

/// Writes the photo (the left view of the stereo pair, or `plx_scene_set_photo`'s, opaque) into
/// the host's image `out` in any `plx_pixel_format` and stride; `out` must have the photo's size.
/// An 8-bit photo written to the same 8-bit layout comes back byte for byte. This is also the
/// composite of a scene with nothing inserted. Errors: `NULL_ARGUMENT`; `NOT_AVAILABLE` without
/// a photo; `SIZE_MISMATCH` when `out` has another size; `INVALID_ARGUMENT` (unknown format,
/// stride shorter than a row). On error `out` is untouched.
///
/// # Safety
/// `scene` is a live scene; `out` points to a valid descriptor of writable memory.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_photo(
    scene: *mut plx_scene,
    out: *const plx_image_out,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let pair = scene.loaded_pair()?;
        let rgb = &pair.left_rgb;
        write_linear(
            out,
            "out",
            rgb.width() as u32,
            rgb.height() as u32,
            |x, y| {
                let [r, g, b] = *rgb.get(x, y);
                [r, g, b, 1.0]
            },
        )
    })
}

/// The photo's size in pixels (the left view of the stereo pair) into `*width` and `*height`:
/// the size every image output of the scene (`plx_scene_photo`, `plx_scene_render`) must have.
/// Cheap: decodes nothing. Errors: `NULL_ARGUMENT`; `NOT_AVAILABLE` without a photo (a stereo
/// pair or `plx_scene_set_photo`).
///
/// # Safety
/// `scene` is a live scene; `width` and `height` are writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_photo_size(
    scene: *mut plx_scene,
    width: *mut u32,
    height: *mut u32,
) -> Status {
    with_scene(scene, |scene| {
        if width.is_null() {
            return Err(null_argument("width"));
        }
        if height.is_null() {
            return Err(null_argument("height"));
        }
        let (w, h) = scene.photo_size().ok_or_else(|| {
            CallError::from(Error::NotAvailable(
                "no photo: set a stereo pair (plx_scene_set_stereo_pair) or a photo (plx_scene_set_photo)"
                .into(),
            ))
        })?;
        *width = w;
        *height = h;
        Ok(())
    })
}

/// Reads a path argument as a file path (bytes as they are on Unix, UTF-8 elsewhere).
unsafe fn c_path(p: *const c_char, name: &str) -> Result<std::path::PathBuf, CallError> {
    if p.is_null() {
        return Err(null_argument(name));
    }
    let bytes = CStr::from_ptr(p).to_bytes();
    #[cfg(unix)]
    {
        Ok(std::path::PathBuf::from(
            <std::ffi::OsStr as std::os::unix::ffi::OsStrExt>::from_bytes(bytes),
        ))
    }
    #[cfg(not(unix))]
    {
        std::str::from_utf8(bytes)
            .map(std::path::PathBuf::from)
            .map_err(|_| invalid(format!("{name} is not valid UTF-8")))
    }
}

/// Reads the stereo pair from two image files (PNG, JPEG, OpenEXR, Radiance HDR; 8-bit files are
/// sRGB, float files linear) and sets it like `plx_scene_set_stereo_pair`. The size is checked
/// against the context's pixel cap before decoding. Errors: `NULL_ARGUMENT`; `IO` (a file cannot
/// be read: the message names it); `FORMAT` (not a decodable image); `TOO_LARGE`;
/// `SIZE_MISMATCH` (the views differ in size, or differ from the host depth). On error the scene
/// is unchanged.
///
/// # Safety
/// `scene` is a live scene; `left_path` and `right_path` are NUL-terminated strings.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_load_stereo_pair(
    scene: *mut plx_scene,
    left_path: *const c_char,
    right_path: *const c_char,
) -> Status {
    with_scene(scene, |scene| {
        let left_path = c_path(left_path, "left_path")?;
        let right_path = c_path(right_path, "right_path")?;
        let limits = scene.context().limits();
        let left = Image::load(&left_path, &limits)?;
        let right = Image::load(&right_path, &limits)?;
        scene
            .set_stereo_pair(&left.view(), &right.view())
            .map_err(|e| match e {
                Error::SizeMismatch(m) => Error::SizeMismatch(format!(
                    "{} and {}: {m}",
                    left_path.display(),
                    right_path.display()
                )),
                other => other,
            })?;
        Ok(())
    })
}
