//! Error-against-run-time scatter plots for the `eval` commands: time on a log axis, error on a
//! linear one, one marker per measured configuration. The legend lives in the Markdown beside
//! the plot (no font rendering here).

use parallax::image::{Image, PixelFormat};
use parallax::Result;

/// One marker.
pub struct Point {
    /// Run time, milliseconds (drawn on a log axis).
    pub ms: f64,
    /// Error, in the plot's unit.
    pub error: f64,
    /// Marker colour (8-bit sRGB).
    pub colour: [u8; 3],
    /// An outlined square (for peers or a second series) instead of a filled one.
    pub hollow: bool,
}

/// The axes: time from 10^`decade_lo` to 10^`decade_hi` ms, error from 0 to `error_max`; a grid
/// line every decade and every tenth of the error range.
pub struct Axes {
    /// Lowest decade of the time axis (ms = 10^decade_lo at the left edge).
    pub decade_lo: i32,
    /// Highest decade (right edge).
    pub decade_hi: i32,
    /// Error at the top edge.
    pub error_max: f64,
}

/// Draws `points` on `axes` as a 640×480 RGB image.
pub fn scatter(points: &[Point], axes: &Axes) -> Result<Image> {
    let (w, h) = (640usize, 480usize);
    let (x0, x1, y0, y1) = (60usize, 620usize, 440usize, 20usize);
    let mut px = vec![255u8; w * h * 3];
    let put = |x: i64, y: i64, c: [u8; 3], px: &mut Vec<u8>| {
        if (0..w as i64).contains(&x) && (0..h as i64).contains(&y) {
            let i = (y as usize * w + x as usize) * 3;
            px[i..i + 3].copy_from_slice(&c);
        }
    };
    let grid = [225, 225, 225];
    for k in 0..=10 {
        let y = y0 - (y0 - y1) * k / 10;
        for x in x0..=x1 {
            put(x as i64, y as i64, grid, &mut px);
        }
    }
    let decades = (axes.decade_hi - axes.decade_lo).max(1);
    for k in 0..=decades as usize {
        let x = x0 + (x1 - x0) * k / decades as usize;
        for y in y1..=y0 {
            put(x as i64, y as i64, grid, &mut px);
        }
    }
    for x in x0..=x1 {
        put(x as i64, y0 as i64, [0, 0, 0], &mut px);
    }
    for y in y1..=y0 {
        put(x0 as i64, y as i64, [0, 0, 0], &mut px);
    }
    let error_max = if axes.error_max > 0.0 {
        axes.error_max
    } else {
        1.0
    };
    for p in points {
        if !p.ms.is_finite() || !p.error.is_finite() {
            continue;
        }
        let t = ((p.ms.max(1e-9).log10() - axes.decade_lo as f64) / decades as f64).clamp(0.0, 1.0);
        let x = x0 as f64 + (x1 - x0) as f64 * t;
        let y = y0 as f64 - (y0 - y1) as f64 * (p.error / error_max).clamp(0.0, 1.0);
        for dy in -5i64..=5 {
            for dx in -5i64..=5 {
                let edge = dx.abs() == 5 || dy.abs() == 5;
                if p.hollow && !edge && dx.abs() < 4 && dy.abs() < 4 {
                    continue;
                }
                put(x as i64 + dx, y as i64 + dy, p.colour, &mut px);
            }
        }
    }
    Image::from_bytes(w as u32, h as u32, PixelFormat::Rgb8, px)
}

/// The smallest "nice" number (1, 2 or 5 × 10^k) at or above `value`, for an axis' top.
pub fn nice_ceiling(value: f64) -> f64 {
    if !value.is_finite() || value <= 0.0 {
        return 1.0;
    }
    let decade = 10f64.powf(value.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * decade)
        .find(|v| *v >= value)
        .unwrap_or(10.0 * decade)
}
