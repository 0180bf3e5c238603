//! Image descriptors crossing the C boundary.

use super::boundary::{invalid, null_argument, CallError};
use crate::image::{ImageView, PixelFormat};

/// Pixel formats of `plx_image::format`.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum plx_pixel_format {
    /// 1 byte: sRGB luminance.
    Gray8 = 0,
    /// 3 bytes: R, G, B (sRGB).
    Rgb8 = 1,
    /// 4 bytes: R, G, B (sRGB), A (linear).
    Rgba8 = 2,
    /// 4 bytes: B, G, R (sRGB), A — Unity/D3D surfaces.
    Bgra8 = 3,
    /// 1 native-endian float, linear.
    GrayF32 = 4,
    /// 3 native-endian floats R, G, B, linear.
    RgbF32 = 5,
    /// 4 native-endian IEEE half floats R, G, B, A, linear.
    RgbaF16 = 6,
    /// 4 native-endian floats R, G, B, A, linear.
    RgbaF32 = 7,
}

/// An image in caller memory: `height` rows of `stride` bytes starting at `data`; each row holds
/// `width` pixels of `format` (a `plx_pixel_format` value). The last row may end right after
/// its last pixel. Parallax copies what it keeps; the memory may be reused after the call.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_image {
    /// First byte of the top row.
    pub data: *const u8,
    /// Pixels per row (> 0).
    pub width: u32,
    /// Rows (> 0).
    pub height: u32,
    /// Bytes from the start of one row to the next (≥ width × bytes per pixel).
    pub stride: usize,
    /// A `plx_pixel_format` value.
    pub format: u32,
}

pub(crate) fn pixel_format(code: u32) -> Result<PixelFormat, CallError> {
    use plx_pixel_format as F;
    let formats = [
        (F::Gray8, PixelFormat::Gray8),
        (F::Rgb8, PixelFormat::Rgb8),
        (F::Rgba8, PixelFormat::Rgba8),
        (F::Bgra8, PixelFormat::Bgra8),
        (F::GrayF32, PixelFormat::GrayF32),
        (F::RgbF32, PixelFormat::RgbF32),
        (F::RgbaF16, PixelFormat::RgbaF16),
        (F::RgbaF32, PixelFormat::RgbaF32),
    ];
    formats
        .into_iter()
        .find(|(c, _)| *c as u32 == code)
        .map(|(_, f)| f)
        .ok_or_else(|| invalid(format!("unknown pixel format {code}")))
}

/// Borrows a `plx_image` as an [`ImageView`], validating everything but the memory itself.
///
/// # Safety
/// `image` is NULL or points to a `plx_image` whose `data` spans `stride × (height − 1) + row`
/// readable bytes.
pub(crate) unsafe fn view<'a>(
    image: *const plx_image,
    name: &str,
) -> Result<ImageView<'a>, CallError> {
    if image.is_null() {
        return Err(null_argument(name));
    }
    let d = &*image;
    if d.data.is_null() {
        return Err(null_argument(&format!("{name}.data")));
    }
    let format = pixel_format(d.format).map_err(|e| invalid(format!("{name}: {}", e.message)))?;
    if d.width == 0 || d.height == 0 {
        return Err(invalid(format!(
            "{name}: size {}x{} has a zero dimension",
            d.width, d.height
        )));
    }
    let row = (d.width as usize)
        .checked_mul(format.bytes_per_pixel())
        .ok_or_else(|| invalid(format!("{name}: width {} overflows", d.width)))?;
    if d.stride < row {
        return Err(invalid(format!(
            "{name}: stride {} bytes is shorter than a row of {} {format:?} pixels ({row} bytes)",
            d.stride, d.width
        )));
    }
    let len = d
        .stride
        .checked_mul(d.height as usize - 1)
        .and_then(|n| n.checked_add(row))
        .filter(|n| *n <= isize::MAX as usize)
        .ok_or_else(|| invalid(format!("{name}: {}x{} overflows memory", d.width, d.height)))?;
    let bytes = std::slice::from_raw_parts(d.data, len);
    ImageView::new(bytes, d.width, d.height, d.stride, format)
        .map_err(CallError::from)
        .map_err(|mut e| {
            e.message = format!("{name}: {}", e.message);
            e
        })
}
