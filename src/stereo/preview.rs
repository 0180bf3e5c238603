//! A colour-mapped picture of a disparity map, for people to look at.

use crate::error::Result;
use crate::image::{Image, PixelFormat, Raster};

/// Colours `disparity` from dark blue (0) through green and yellow to dark red (`max`); pixels
/// without an estimate are black. `max ≤ 0` or non-finite uses the map's own largest value.
///
/// # Errors
/// `InvalidArgument` for an empty raster.
pub fn colorize(disparity: &Raster<f32>, max: f32) -> Result<Image> {
    let top = if max.is_finite() && max > 0.0 {
        max
    } else {
        disparity
            .pixels()
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0f32, f32::max)
            .max(1e-6)
    };
    let mut data = Vec::with_capacity(disparity.len() * 3);
    for &d in disparity.pixels() {
        if d.is_finite() {
            data.extend_from_slice(&jet((d / top).clamp(0.0, 1.0)));
        } else {
            data.extend_from_slice(&[0, 0, 0]);
        }
    }
    Image::from_bytes(
        disparity.width() as u32,
        disparity.height() as u32,
        PixelFormat::Rgb8,
        data,
    )
}

/// The classic "jet" colour ramp at `t` in [0, 1].
pub fn jet(t: f32) -> [u8; 3] {
    let channel =
        |offset: f32| ((1.5 - (4.0 * t - offset).abs()).clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [channel(3.0), channel(2.0), channel(1.0)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_ends_and_holes() {
        assert_eq!(jet(0.0), [0, 0, 128]);
        assert_eq!(jet(1.0), [128, 0, 0]);
        assert_eq!(jet(0.5), [128, 255, 128]);
        let d = Raster::from_vec(3, 1, vec![0.0, f32::NAN, 10.0]);
        let img = colorize(&d, 10.0).unwrap();
        assert_eq!(&img.as_bytes()[3..6], &[0, 0, 0]);
        assert_eq!(&img.as_bytes()[6..9], &[128, 0, 0]);
    }
}
