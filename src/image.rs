//! Image buffers and views, colour conversion, and file I/O (PNG, JPEG, PFM, OpenEXR, Radiance HDR).
//!
//! Two kinds of image live here:
//! - [`Image`] / [`ImageView`]: bytes in a [`PixelFormat`] with a row stride, as they arrive from
//!   files and from C hosts;
//! - [`Raster<T>`]: a packed, row-major grid of one value type (`f32`, `[f32; 3]`, `u8`, …), which
//!   is what every stage computes on. Colour rasters hold **linear** light.
//!
//! Pixels are row-major with the origin at the top-left (DESIGN.md, "Conventions").

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::Path;

use crate::error::{Error, Result};

/// The default cap on the number of pixels of any image Parallax accepts (64 megapixels).
pub const DEFAULT_MAX_PIXELS: u64 = 64 * 1024 * 1024;

/// Caps checked before any image is allocated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageLimits {
    /// Largest accepted `width × height`.
    pub max_pixels: u64,
}

impl Default for ImageLimits {
    fn default() -> Self {
        ImageLimits {
            max_pixels: DEFAULT_MAX_PIXELS,
        }
    }
}

impl ImageLimits {
    /// Checks `width × height` against the cap and that neither is zero.
    ///
    /// # Errors
    /// `InvalidArgument` for a zero dimension, `TooLarge` over the cap. `what` names the image in
    /// the message.
    pub fn check(&self, what: &str, width: u64, height: u64) -> Result<()> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!(
                "{what}: size {width}x{height} has a zero dimension"
            )));
        }
        let pixels = width.saturating_mul(height);
        if pixels > self.max_pixels {
            return Err(Error::TooLarge(format!(
                "{what}: {width}x{height} = {pixels} pixels exceeds the cap of {} pixels",
                self.max_pixels
            )));
        }
        Ok(())
    }
}

/// How the bytes of one pixel are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PixelFormat {
    /// One byte, sRGB-encoded luminance.
    Gray8,
    /// Three bytes R, G, B, sRGB-encoded.
    Rgb8,
    /// Four bytes R, G, B, A; colour sRGB-encoded, alpha linear.
    Rgba8,
    /// Four bytes B, G, R, A (Windows/Unity/D3D surfaces); colour sRGB-encoded.
    Bgra8,
    /// One native-endian `f32`, linear.
    GrayF32,
    /// Three native-endian `f32` R, G, B, linear.
    RgbF32,
    /// Four native-endian IEEE half floats R, G, B, A, linear.
    RgbaF16,
    /// Four native-endian `f32` R, G, B, A, linear.
    RgbaF32,
}

impl PixelFormat {
    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            PixelFormat::Gray8 => 1,
            PixelFormat::Rgb8 => 3,
            PixelFormat::Rgba8 | PixelFormat::Bgra8 => 4,
            PixelFormat::GrayF32 => 4,
            PixelFormat::RgbF32 => 12,
            PixelFormat::RgbaF16 => 8,
            PixelFormat::RgbaF32 => 16,
        }
    }

    /// Whether the colour channels are sRGB-encoded 8-bit values (else linear floats).
    pub fn is_srgb8(self) -> bool {
        matches!(
            self,
            PixelFormat::Gray8 | PixelFormat::Rgb8 | PixelFormat::Rgba8 | PixelFormat::Bgra8
        )
    }
}

/// A borrowed image: bytes, size, row stride in bytes and pixel format.
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a> {
    data: &'a [u8],
    width: u32,
    height: u32,
    stride: usize,
    format: PixelFormat,
}

impl<'a> ImageView<'a> {
    /// Wraps `data` as an image, checking that it holds `height` rows of `stride` bytes (the last
    /// row may stop at its last pixel) and that `stride` fits a row.
    ///
    /// # Errors
    /// `InvalidArgument` for a zero size or a stride shorter than a row; `SizeMismatch` when `data`
    /// is too short.
    pub fn new(
        data: &'a [u8],
        width: u32,
        height: u32,
        stride: usize,
        format: PixelFormat,
    ) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!(
                "image size {width}x{height} has a zero dimension"
            )));
        }
        let row = (width as usize)
            .checked_mul(format.bytes_per_pixel())
            .ok_or_else(|| Error::TooLarge(format!("image row of {width} pixels overflows")))?;
        if stride < row {
            return Err(Error::invalid(format!(
                "stride {stride} bytes is shorter than a row of {width} {format:?} pixels ({row} bytes)"
            )));
        }
        let needed = stride
            .checked_mul(height as usize - 1)
            .and_then(|n| n.checked_add(row))
            .ok_or_else(|| Error::TooLarge(format!("image {width}x{height} overflows memory")))?;
        if data.len() < needed {
            return Err(Error::SizeMismatch(format!(
                "image {width}x{height} {format:?} with stride {stride} needs {needed} bytes, got {}",
                data.len()
            )));
        }
        Ok(ImageView {
            data,
            width,
            height,
            stride,
            format,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Bytes from one row to the next.
    pub fn stride(&self) -> usize {
        self.stride
    }
    /// Pixel format.
    pub fn format(&self) -> PixelFormat {
        self.format
    }

    /// The bytes of row `y` (exactly `width × bytes_per_pixel` long).
    ///
    /// # Panics
    /// If `y >= height`.
    pub fn row(&self, y: u32) -> &'a [u8] {
        let start = y as usize * self.stride;
        &self.data[start..start + self.width as usize * self.format.bytes_per_pixel()]
    }

    /// Copies into an owned image with a packed stride.
    pub fn to_owned_image(&self) -> Image {
        let row = self.width as usize * self.format.bytes_per_pixel();
        let mut data = Vec::with_capacity(row * self.height as usize);
        for y in 0..self.height {
            data.extend_from_slice(self.row(y));
        }
        Image {
            data,
            width: self.width,
            height: self.height,
            format: self.format,
        }
    }

    /// Linear RGB of every pixel (sRGB decoded for 8-bit formats; alpha dropped).
    pub fn to_linear_rgb(&self) -> Raster<[f32; 3]> {
        let lut = srgb8_to_linear_table();
        let bpp = self.format.bytes_per_pixel();
        let mut out = Vec::with_capacity(self.width as usize * self.height as usize);
        for y in 0..self.height {
            let row = self.row(y);
            for px in row.chunks_exact(bpp) {
                out.push(decode_pixel(self.format, px, &lut));
            }
        }
        Raster::from_vec(self.width as usize, self.height as usize, out)
    }

    /// Luminance (Rec. 709 weights) of the **encoded** values in [0, 1]: for 8-bit formats the
    /// sRGB code values themselves, so it is perceptually spaced, which is what block matching wants.
    /// Float formats are taken as they are (linear).
    pub fn to_luma(&self) -> Raster<f32> {
        let bpp = self.format.bytes_per_pixel();
        let mut out = Vec::with_capacity(self.width as usize * self.height as usize);
        for y in 0..self.height {
            let row = self.row(y);
            for px in row.chunks_exact(bpp) {
                out.push(rec709_luma(encoded_rgb(self.format, px)));
            }
        }
        Raster::from_vec(self.width as usize, self.height as usize, out)
    }
}

/// Rec. 709 luminance of RGB values, in their own units (linear or encoded).
#[inline(always)]
pub fn rec709_luma([r, g, b]: [f32; 3]) -> f32 {
    0.2126 * r + 0.7152 * g + 0.0722 * b
}

/// An owned image with packed rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    data: Vec<u8>,
    width: u32,
    height: u32,
    format: PixelFormat,
}

impl Image {
    /// Wraps packed pixel bytes.
    ///
    /// # Errors
    /// `InvalidArgument` for a zero size, `SizeMismatch` when `data.len()` is not
    /// `width × height × bytes_per_pixel`.
    pub fn from_bytes(width: u32, height: u32, format: PixelFormat, data: Vec<u8>) -> Result<Self> {
        let expected = (width as usize)
            .checked_mul(height as usize)
            .and_then(|n| n.checked_mul(format.bytes_per_pixel()))
            .ok_or_else(|| Error::TooLarge(format!("image {width}x{height} overflows memory")))?;
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!(
                "image size {width}x{height} has a zero dimension"
            )));
        }
        if data.len() != expected {
            return Err(Error::SizeMismatch(format!(
                "image {width}x{height} {format:?} needs {expected} bytes, got {}",
                data.len()
            )));
        }
        Ok(Image {
            data,
            width,
            height,
            format,
        })
    }

    /// A borrowed view of the whole image.
    pub fn view(&self) -> ImageView<'_> {
        ImageView {
            data: &self.data,
            width: self.width,
            height: self.height,
            stride: self.width as usize * self.format.bytes_per_pixel(),
            format: self.format,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Pixel format.
    pub fn format(&self) -> PixelFormat {
        self.format
    }
    /// The packed pixel bytes.
    pub fn as_bytes(&self) -> &[u8] {
        &self.data
    }
    /// Bytes from one row to the next (packed).
    pub fn stride(&self) -> usize {
        self.width as usize * self.format.bytes_per_pixel()
    }

    /// Linear RGB (see [`ImageView::to_linear_rgb`]).
    pub fn to_linear_rgb(&self) -> Raster<[f32; 3]> {
        self.view().to_linear_rgb()
    }

    /// Luminance of the encoded values (see [`ImageView::to_luma`]).
    pub fn to_luma(&self) -> Raster<f32> {
        self.view().to_luma()
    }

    /// Encodes linear RGB as 8-bit sRGB (values clamped to [0, 1]; NaN becomes 0).
    pub fn from_linear_rgb(raster: &Raster<[f32; 3]>) -> Image {
        let mut data = Vec::with_capacity(raster.len() * 3);
        for p in raster.pixels() {
            for c in p {
                data.push(linear_to_srgb8(*c));
            }
        }
        Image {
            data,
            width: raster.width() as u32,
            height: raster.height() as u32,
            format: PixelFormat::Rgb8,
        }
    }

    /// Loads PNG, JPEG, OpenEXR or Radiance HDR, checking the size against `limits` before the
    /// pixels are decoded. 8-bit files give `Rgb8`/`Rgba8`/`Gray8`; 16-bit and float files give
    /// `RgbF32`/`RgbaF32` (16-bit PNG is taken as sRGB and decoded to linear).
    ///
    /// # Errors
    /// `Io` when the file cannot be opened, `Format` when it cannot be decoded, `TooLarge` over the cap.
    pub fn load(path: impl AsRef<Path>, limits: &ImageLimits) -> Result<Image> {
        let path = path.as_ref();
        let open = || -> Result<image::ImageReader<BufReader<File>>> {
            image::ImageReader::open(path)
                .map_err(|e| Error::io(path, e))?
                .with_guessed_format()
                .map_err(|e| Error::io(path, e))
        };
        decode(open, &path.display().to_string(), limits)
    }

    /// Like [`Image::load`] from bytes in memory (format guessed from the content).
    ///
    /// # Errors
    /// As [`Image::load`].
    pub fn load_from_memory(bytes: &[u8], limits: &ImageLimits) -> Result<Image> {
        let open = || {
            image::ImageReader::new(std::io::Cursor::new(bytes))
                .with_guessed_format()
                .map_err(|e| Error::format(format!("image in memory: {e}")))
        };
        decode(open, "image in memory", limits)
    }

    /// Saves as PNG (8-bit formats as they are; BGRA8 reordered; float formats encoded to sRGB).
    ///
    /// # Errors
    /// `Io` when the file cannot be written.
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let (color, bytes): (image::ExtendedColorType, std::borrow::Cow<[u8]>) = match self.format {
            PixelFormat::Gray8 => (image::ExtendedColorType::L8, (&self.data[..]).into()),
            PixelFormat::Rgb8 => (image::ExtendedColorType::Rgb8, (&self.data[..]).into()),
            PixelFormat::Rgba8 => (image::ExtendedColorType::Rgba8, (&self.data[..]).into()),
            PixelFormat::Bgra8 => {
                let mut v = self.data.clone();
                for px in v.chunks_exact_mut(4) {
                    px.swap(0, 2);
                }
                (image::ExtendedColorType::Rgba8, v.into())
            }
            _ => {
                let srgb = Image::from_linear_rgb(&self.to_linear_rgb());
                return srgb.save_png(path);
            }
        };
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        let encoder = image::codecs::png::PngEncoder::new(BufWriter::new(file));
        image::ImageEncoder::write_image(encoder, &bytes, self.width, self.height, color)
            .map_err(|e| image_error(path, e))
    }
}

fn image_error(path: &Path, e: image::ImageError) -> Error {
    match e {
        image::ImageError::IoError(io) => Error::io(path, io),
        other => Error::format(format!("{}: {other}", path.display())),
    }
}

/// Reads the header for the size, checks it against the cap, then decodes. `open` is called twice
/// because `image` consumes the reader to report dimensions.
fn decode<R: BufRead + std::io::Seek>(
    mut open: impl FnMut() -> Result<image::ImageReader<R>>,
    name: &str,
    limits: &ImageLimits,
) -> Result<Image> {
    let with_limits = |mut reader: image::ImageReader<R>| {
        let mut decode_limits = image::Limits::default();
        // Decoders may allocate more than the pixels themselves; 16 bytes a pixel covers RGBA f32.
        decode_limits.max_alloc = Some(limits.max_pixels.saturating_mul(16).max(1 << 20));
        reader.limits(decode_limits);
        reader
    };
    let header = with_limits(open()?);
    if header.format().is_none() {
        return Err(Error::format(format!("{name}: unknown image format")));
    }
    let (w, h) = header
        .into_dimensions()
        .map_err(|e| Error::format(format!("{name}: {e}")))?;
    limits.check(name, w as u64, h as u64)?;
    let decoded = with_limits(open()?)
        .decode()
        .map_err(|e| Error::format(format!("{name}: {e}")))?;
    use image::DynamicImage as D;
    let (format, data) = match decoded {
        D::ImageLuma8(b) => (PixelFormat::Gray8, b.into_raw()),
        D::ImageRgb8(b) => (PixelFormat::Rgb8, b.into_raw()),
        D::ImageRgba8(b) => (PixelFormat::Rgba8, b.into_raw()),
        D::ImageLumaA8(_) => (PixelFormat::Rgba8, decoded_to_rgba8(decoded)),
        D::ImageRgb32F(b) => (PixelFormat::RgbF32, f32_bytes(b.into_raw())),
        D::ImageRgba32F(b) => (PixelFormat::RgbaF32, f32_bytes(b.into_raw())),
        other => {
            // 16-bit integer files: sRGB-coded like 8-bit ones, kept at full precision as floats.
            let has_alpha = other.color().has_alpha();
            let mut values = other.to_rgba32f().into_raw();
            for px in values.chunks_exact_mut(4) {
                for c in &mut px[..3] {
                    *c = srgb_to_linear(*c);
                }
            }
            if has_alpha {
                (PixelFormat::RgbaF32, f32_bytes(values))
            } else {
                let rgb: Vec<f32> = values
                    .chunks_exact(4)
                    .flat_map(|p| [p[0], p[1], p[2]])
                    .collect();
                (PixelFormat::RgbF32, f32_bytes(rgb))
            }
        }
    };
    Image::from_bytes(w, h, format, data)
}

fn decoded_to_rgba8(image: image::DynamicImage) -> Vec<u8> {
    image.to_rgba8().into_raw()
}

fn f32_bytes(values: Vec<f32>) -> Vec<u8> {
    bytemuck::cast_slice(&values).to_vec()
}

fn srgb8_to_linear_table() -> [f32; 256] {
    let mut t = [0.0; 256];
    for (i, v) in t.iter_mut().enumerate() {
        *v = srgb_to_linear(i as f32 / 255.0);
    }
    t
}

fn decode_pixel(format: PixelFormat, px: &[u8], lut: &[f32; 256]) -> [f32; 3] {
    match format {
        PixelFormat::Gray8 => {
            let v = lut[px[0] as usize];
            [v, v, v]
        }
        PixelFormat::Rgb8 | PixelFormat::Rgba8 => [
            lut[px[0] as usize],
            lut[px[1] as usize],
            lut[px[2] as usize],
        ],
        PixelFormat::Bgra8 => [
            lut[px[2] as usize],
            lut[px[1] as usize],
            lut[px[0] as usize],
        ],
        _ => float_rgb(format, px).map(sanitize_linear),
    }
}

/// Colour as stored: 8-bit code values scaled to [0, 1], floats as they are (NaN → 0).
fn encoded_rgb(format: PixelFormat, px: &[u8]) -> [f32; 3] {
    const S: f32 = 1.0 / 255.0;
    match format {
        PixelFormat::Gray8 => [px[0] as f32 * S; 3],
        PixelFormat::Rgb8 | PixelFormat::Rgba8 => {
            [px[0] as f32 * S, px[1] as f32 * S, px[2] as f32 * S]
        }
        PixelFormat::Bgra8 => [px[2] as f32 * S, px[1] as f32 * S, px[0] as f32 * S],
        _ => float_rgb(format, px).map(sanitize_linear),
    }
}

fn float_rgb(format: PixelFormat, px: &[u8]) -> [f32; 3] {
    let f = |i: usize| f32::from_ne_bytes([px[4 * i], px[4 * i + 1], px[4 * i + 2], px[4 * i + 3]]);
    let h = |i: usize| half::f16::from_ne_bytes([px[2 * i], px[2 * i + 1]]).to_f32();
    match format {
        PixelFormat::GrayF32 => [f(0); 3],
        PixelFormat::RgbF32 | PixelFormat::RgbaF32 => [f(0), f(1), f(2)],
        PixelFormat::RgbaF16 => [h(0), h(1), h(2)],
        _ => unreachable!("float_rgb called with 8-bit format {format:?}"),
    }
}

/// Linear light must be finite and non-negative; NaN and negatives become 0, +inf the largest f32.
fn sanitize_linear(v: f32) -> f32 {
    if v.is_nan() || v <= 0.0 {
        0.0
    } else {
        v.min(f32::MAX)
    }
}

/// sRGB transfer function, decoding: code value in [0, 1] → linear.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// sRGB transfer function, encoding: linear → code value in [0, 1] (input clamped to [0, 1]).
pub fn linear_to_srgb(l: f32) -> f32 {
    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
    if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear → 8-bit sRGB code value, rounded.
pub fn linear_to_srgb8(l: f32) -> u8 {
    (linear_to_srgb(l) * 255.0 + 0.5) as u8
}

/// A packed, row-major grid of `T`, `width × height` values.
#[derive(Debug, Clone, PartialEq)]
pub struct Raster<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

impl<T: Clone> Raster<T> {
    /// A raster filled with `value`.
    pub fn filled(width: usize, height: usize, value: T) -> Self {
        Raster {
            width,
            height,
            data: vec![value; width * height],
        }
    }
}

impl<T> Raster<T> {
    /// Wraps row-major values.
    ///
    /// # Panics
    /// If `data.len() != width * height` (a programming error, not an input error).
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Self {
        assert_eq!(data.len(), width * height, "raster data length");
        Raster {
            width,
            height,
            data,
        }
    }

    /// Builds a raster by calling `f(x, y)` for every pixel.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> T) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Raster {
            width,
            height,
            data,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.data.len()
    }
    /// Whether the raster has no pixels.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    /// All values, row-major.
    pub fn pixels(&self) -> &[T] {
        &self.data
    }
    /// All values, row-major, mutable.
    pub fn pixels_mut(&mut self) -> &mut [T] {
        &mut self.data
    }
    /// Consumes the raster, returning its values.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }
    /// The value at (x, y).
    ///
    /// # Panics
    /// Out of bounds.
    pub fn get(&self, x: usize, y: usize) -> &T {
        &self.data[y * self.width + x]
    }
    /// The value at (x, y), mutable.
    ///
    /// # Panics
    /// Out of bounds.
    pub fn get_mut(&mut self, x: usize, y: usize) -> &mut T {
        &mut self.data[y * self.width + x]
    }
    /// Row `y`.
    pub fn row(&self, y: usize) -> &[T] {
        &self.data[y * self.width..(y + 1) * self.width]
    }
    /// Row `y`, mutable.
    pub fn row_mut(&mut self, y: usize) -> &mut [T] {
        &mut self.data[y * self.width..(y + 1) * self.width]
    }
    /// A raster of the same size with `f` applied to every value.
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> Raster<U> {
        Raster {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }
}

impl Raster<f32> {
    /// Reads a PFM file (grey `Pf` or colour `PF`, whose luminance-free first channel is kept).
    /// Rows are stored bottom to top; `inf` (Middlebury's "unknown") becomes NaN in memory.
    /// Either byte order is accepted (negative scale = little-endian).
    ///
    /// # Errors
    /// `Io`, `Format` for a malformed header or short data, `TooLarge` over `limits`.
    pub fn read_pfm(path: impl AsRef<Path>, limits: &ImageLimits) -> Result<Raster<f32>> {
        let (w, h, channels, values) = read_pfm_values(path.as_ref(), limits)?;
        let data = values.chunks_exact(channels).map(|c| c[0]).collect();
        Ok(Raster::from_vec(w, h, data))
    }

    /// Writes a grey PFM: little-endian, rows bottom to top, NaN written as `inf`.
    ///
    /// # Errors
    /// `Io`.
    pub fn write_pfm(&self, path: impl AsRef<Path>) -> Result<()> {
        write_pfm_values(path.as_ref(), self.width, self.height, 1, |x, y, _| {
            *self.get(x, y)
        })
    }
}

impl Raster<[f32; 3]> {
    /// Reads a colour PFM (`PF`); a grey one is expanded to three equal channels.
    ///
    /// # Errors
    /// As [`Raster::<f32>::read_pfm`].
    pub fn read_pfm_rgb(path: impl AsRef<Path>, limits: &ImageLimits) -> Result<Self> {
        let (w, h, channels, values) = read_pfm_values(path.as_ref(), limits)?;
        let data = values
            .chunks_exact(channels)
            .map(|c| {
                if channels == 3 {
                    [c[0], c[1], c[2]]
                } else {
                    [c[0]; 3]
                }
            })
            .collect();
        Ok(Raster::from_vec(w, h, data))
    }

    /// Writes a colour PFM (`PF`), little-endian, bottom to top, NaN as `inf`.
    ///
    /// # Errors
    /// `Io`.
    pub fn write_pfm(&self, path: impl AsRef<Path>) -> Result<()> {
        write_pfm_values(path.as_ref(), self.width, self.height, 3, |x, y, c| {
            self.get(x, y)[c]
        })
    }

    /// Writes linear RGB as OpenEXR (32-bit float channels).
    ///
    /// # Errors
    /// `Io`, or `Format` if the encoder rejects the data.
    pub fn write_exr(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let flat: Vec<f32> = self.data.iter().flatten().copied().collect();
        let buffer: image::Rgb32FImage =
            image::ImageBuffer::from_raw(self.width as u32, self.height as u32, flat)
                .ok_or_else(|| Error::Internal("EXR buffer size".into()))?;
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        let encoder = image::codecs::openexr::OpenExrEncoder::new(BufWriter::new(file));
        image::ImageEncoder::write_image(
            encoder,
            bytemuck::cast_slice(buffer.as_raw()),
            self.width as u32,
            self.height as u32,
            image::ExtendedColorType::Rgb32F,
        )
        .map_err(|e| image_error(path, e))
    }

    /// Reads an OpenEXR or Radiance HDR file as linear RGB (non-finite and negative values become 0).
    ///
    /// # Errors
    /// As [`Image::load`].
    pub fn read_hdr(path: impl AsRef<Path>, limits: &ImageLimits) -> Result<Self> {
        Ok(Image::load(path, limits)?.to_linear_rgb())
    }
}

const PFM_HEADER_LIMIT: usize = 256;

fn read_pfm_values(path: &Path, limits: &ImageLimits) -> Result<(usize, usize, usize, Vec<f32>)> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = BufReader::new(file);
    // The header is three whitespace-separated tokens after the magic; read them byte by byte so
    // that a binary file without newlines cannot make us read it all as "header".
    let mut tokens: Vec<String> = Vec::new();
    let mut current = Vec::new();
    let mut consumed = 0;
    while tokens.len() < 4 {
        let mut byte = [0u8];
        let n = reader.read(&mut byte).map_err(|e| Error::io(path, e))?;
        consumed += 1;
        if n == 0 || consumed > PFM_HEADER_LIMIT {
            return Err(Error::format(format!(
                "{name}: truncated or malformed PFM header"
            )));
        }
        if byte[0].is_ascii_whitespace() {
            if !current.is_empty() {
                tokens.push(String::from_utf8_lossy(&current).into_owned());
                current.clear();
            }
        } else {
            current.push(byte[0]);
        }
    }
    let channels = match tokens[0].as_str() {
        "Pf" => 1,
        "PF" => 3,
        other => {
            return Err(Error::format(format!(
                "{name}: not a PFM file (magic {other:?}, expected \"Pf\" or \"PF\")"
            )))
        }
    };
    let parse_dim = |s: &str| {
        s.parse::<u64>()
            .map_err(|_| Error::format(format!("{name}: bad PFM dimension {s:?}")))
    };
    let (w, h) = (parse_dim(&tokens[1])?, parse_dim(&tokens[2])?);
    let scale: f32 = tokens[3]
        .parse()
        .map_err(|_| Error::format(format!("{name}: bad PFM scale {:?}", tokens[3])))?;
    if !scale.is_finite() || scale == 0.0 {
        return Err(Error::format(format!("{name}: bad PFM scale {scale}")));
    }
    limits.check(&name, w, h)?;
    let (w, h) = (w as usize, h as usize);
    let count = w * h * channels;
    let mut bytes = vec![0u8; count * 4];
    reader.read_exact(&mut bytes).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            Error::format(format!("{name}: PFM data shorter than {w}x{h}x{channels}"))
        } else {
            Error::io(path, e)
        }
    })?;
    let little = scale < 0.0;
    let mut values = vec![0.0f32; count];
    let row_len = w * channels;
    for (file_row, chunk) in bytes.chunks_exact(row_len * 4).enumerate() {
        let y = h - 1 - file_row;
        for (i, b) in chunk.chunks_exact(4).enumerate() {
            let raw = [b[0], b[1], b[2], b[3]];
            let v = if little {
                f32::from_le_bytes(raw)
            } else {
                f32::from_be_bytes(raw)
            };
            values[y * row_len + i] = if v.is_infinite() { f32::NAN } else { v };
        }
    }
    Ok((w, h, channels, values))
}

fn write_pfm_values(
    path: &Path,
    width: usize,
    height: usize,
    channels: usize,
    value: impl Fn(usize, usize, usize) -> f32,
) -> Result<()> {
    let file = File::create(path).map_err(|e| Error::io(path, e))?;
    let mut out = BufWriter::new(file);
    let magic = if channels == 1 { "Pf" } else { "PF" };
    let mut write = || -> std::io::Result<()> {
        write!(out, "{magic}\n{width} {height}\n-1\n")?;
        for y in (0..height).rev() {
            for x in 0..width {
                for c in 0..channels {
                    let v = value(x, y, c);
                    let v = if v.is_nan() { f32::INFINITY } else { v };
                    out.write_all(&v.to_le_bytes())?;
                }
            }
        }
        out.flush()
    };
    write().map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_is_exact_for_every_code_value() {
        for i in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb_to_linear(i as f32 / 255.0)), i);
        }
    }

    #[test]
    fn srgb_encoding_clamps_and_never_yields_nan() {
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(1e30), 255);
        assert_eq!(linear_to_srgb8(f32::INFINITY), 255);
    }

    #[test]
    fn view_rejects_short_stride_and_short_data() {
        let data = vec![0u8; 100];
        assert!(matches!(
            ImageView::new(&data, 10, 2, 20, PixelFormat::Rgb8),
            Err(Error::InvalidArgument(_))
        ));
        assert!(matches!(
            ImageView::new(&data, 10, 4, 30, PixelFormat::Rgb8),
            Err(Error::SizeMismatch(_))
        ));
        assert!(matches!(
            ImageView::new(&data, 0, 4, 30, PixelFormat::Rgb8),
            Err(Error::InvalidArgument(_))
        ));
        // Last row may end at its last pixel: 2 rows of stride 40, row 30 bytes → 70 bytes.
        assert!(ImageView::new(&data[..70], 10, 2, 40, PixelFormat::Rgb8).is_ok());
    }

    #[test]
    fn strided_view_reads_the_right_pixels() {
        // 2x2 BGRA with 4 bytes of padding per row.
        let data = [
            0u8, 0, 255, 255, 0, 255, 0, 255, 9, 9, 9, 9, //
            255, 0, 0, 255, 255, 255, 255, 255, 9, 9, 9, 9,
        ];
        let v = ImageView::new(&data, 2, 2, 12, PixelFormat::Bgra8).unwrap();
        let rgb = v.to_linear_rgb();
        assert_eq!(*rgb.get(0, 0), [1.0, 0.0, 0.0]);
        assert_eq!(*rgb.get(1, 0), [0.0, 1.0, 0.0]);
        assert_eq!(*rgb.get(0, 1), [0.0, 0.0, 1.0]);
        assert_eq!(*rgb.get(1, 1), [1.0, 1.0, 1.0]);
        assert_eq!(v.to_owned_image().as_bytes().len(), 16);
    }

    #[test]
    fn float_inputs_are_sanitized() {
        let px: Vec<u8> = [f32::NAN, -3.0, f32::INFINITY]
            .iter()
            .flat_map(|v| v.to_ne_bytes())
            .collect();
        let img = Image::from_bytes(1, 1, PixelFormat::RgbF32, px).unwrap();
        let rgb = img.to_linear_rgb();
        assert_eq!(*rgb.get(0, 0), [0.0, 0.0, f32::MAX]);
    }

    #[test]
    fn half_float_pixels_decode() {
        let px: Vec<u8> = [0.5f32, 2.0, 0.25, 1.0]
            .iter()
            .flat_map(|v| half::f16::from_f32(*v).to_ne_bytes())
            .collect();
        let img = Image::from_bytes(1, 1, PixelFormat::RgbaF16, px).unwrap();
        assert_eq!(*img.to_linear_rgb().get(0, 0), [0.5, 2.0, 0.25]);
    }

    #[test]
    fn pfm_round_trip_keeps_nan_and_orientation() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.pfm");
        let r = Raster::from_fn(3, 2, |x, y| {
            if x == 2 && y == 0 {
                f32::NAN
            } else {
                (x + 10 * y) as f32
            }
        });
        r.write_pfm(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.starts_with(b"Pf\n3 2\n-1\n"));
        // First stored row is the bottom row (y = 1): 10, 11, 12.
        assert_eq!(f32::from_le_bytes(bytes[10..14].try_into().unwrap()), 10.0);
        let back = Raster::<f32>::read_pfm(&path, &ImageLimits::default()).unwrap();
        assert_eq!(back.width(), 3);
        assert!(back.get(2, 0).is_nan());
        assert_eq!(*back.get(1, 1), 11.0);
        // NaN is written as +inf (Middlebury's "unknown").
        assert_eq!(f32::from_le_bytes(bytes[22..26].try_into().unwrap()), 0.0);
        assert_eq!(
            f32::from_le_bytes(bytes[30..34].try_into().unwrap()),
            f32::INFINITY
        );
    }

    #[test]
    fn pfm_rejects_garbage_and_oversize() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.pfm");
        std::fs::write(&p, b"P6\n1 1\n255\n\0\0\0").unwrap();
        assert!(matches!(
            Raster::<f32>::read_pfm(&p, &ImageLimits::default()),
            Err(Error::Format(_))
        ));
        std::fs::write(&p, b"Pf\n100000 100000\n-1\n").unwrap();
        assert!(matches!(
            Raster::<f32>::read_pfm(&p, &ImageLimits::default()),
            Err(Error::TooLarge(_))
        ));
        std::fs::write(&p, b"Pf\n2 2\n-1\n\0\0\0\0").unwrap();
        assert!(matches!(
            Raster::<f32>::read_pfm(&p, &ImageLimits::default()),
            Err(Error::Format(_))
        ));
        std::fs::write(&p, vec![b'x'; 1000]).unwrap();
        assert!(matches!(
            Raster::<f32>::read_pfm(&p, &ImageLimits::default()),
            Err(Error::Format(_))
        ));
    }

    #[test]
    fn png_round_trip_and_size_cap_before_decoding() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let img = Image::from_bytes(
            4,
            3,
            PixelFormat::Rgb8,
            (0..36).map(|i| i as u8 * 7).collect(),
        )
        .unwrap();
        img.save_png(&path).unwrap();
        let back = Image::load(&path, &ImageLimits::default()).unwrap();
        assert_eq!(back, img);
        let tiny = ImageLimits { max_pixels: 11 };
        assert!(matches!(Image::load(&path, &tiny), Err(Error::TooLarge(_))));
        assert!(matches!(
            Image::load(dir.path().join("none.png"), &tiny),
            Err(Error::Io { .. })
        ));
        assert!(matches!(
            Image::load_from_memory(b"not an image", &tiny),
            Err(Error::Format(_))
        ));
    }

    #[test]
    fn radiance_hdr_is_read_as_linear_floats() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.hdr");
        let pixels = [
            image::Rgb([0.5f32, 8.0, 1000.0]),
            image::Rgb([0.0, 0.25, 2.0]),
        ];
        let file = std::fs::File::create(&path).unwrap();
        image::codecs::hdr::HdrEncoder::new(file)
            .encode(&pixels, 2, 1)
            .unwrap();
        let back = Raster::<[f32; 3]>::read_hdr(&path, &ImageLimits::default()).unwrap();
        assert_eq!(back.width(), 2);
        // RGBE shares one exponent: precision is about 1 % of the brightest channel.
        for (got, want) in back.pixels().iter().zip(pixels.iter()) {
            let scale = want.0.iter().fold(0.0f32, |a, b| a.max(*b));
            for c in 0..3 {
                assert!(
                    (got[c] - want.0[c]).abs() <= 0.01 * scale,
                    "{got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn exr_round_trip_keeps_hdr_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let r = Raster::from_fn(5, 4, |x, y| {
            [x as f32 * 100.0, y as f32 * 0.001, 65504.0 * 4.0]
        });
        r.write_exr(&path).unwrap();
        let back = Raster::<[f32; 3]>::read_hdr(&path, &ImageLimits::default()).unwrap();
        assert_eq!(back, r);
    }
}
