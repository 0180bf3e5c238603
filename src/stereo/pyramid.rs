//! Coarse-to-fine search (the thesis' Gaussian pyramid, §3.2.1): the pair is reduced to half size,
//! matched there over half the range, and each full-size pixel then searches only a window of
//! disparities around twice the coarse answer.

use rayon::prelude::*;

use crate::image::Raster;

/// Gaussian reduce: 5-tap binomial filter `[1 4 6 4 1]/16` in x and y, then every second pixel.
pub fn reduce(image: &Raster<u8>) -> Raster<u8> {
    let (w, h) = (image.width(), image.height());
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    let taps = [1u32, 4, 6, 4, 1];
    let clamp = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
    // Horizontal pass on every row, at the coarse columns only.
    let mut tmp = vec![0u32; cw * h];
    tmp.par_chunks_mut(cw).enumerate().for_each(|(y, out)| {
        let row = image.row(y);
        for (cx, o) in out.iter_mut().enumerate() {
            let x = 2 * cx as isize;
            *o = (0..5)
                .map(|i| taps[i] * row[clamp(x + i as isize - 2, w)] as u32)
                .sum();
        }
    });
    let mut out = vec![0u8; cw * ch];
    out.par_chunks_mut(cw).enumerate().for_each(|(cy, row)| {
        let y = 2 * cy as isize;
        for (cx, o) in row.iter_mut().enumerate() {
            let s: u32 = (0..5)
                .map(|j| taps[j] * tmp[clamp(y + j as isize - 2, h) * cw + cx])
                .sum();
            *o = ((s + 128) / 256) as u8;
        }
    });
    Raster::from_vec(cw, ch, out)
}

/// Per-pixel window starts for a `width × height` level from the coarse level's dense disparity:
/// each window of `k` disparities (clamped to `0..=max_disparity`) covers the disparities of the
/// 3×3 coarse neighbourhood when they fit in it, else centres on the pixel's own coarse value.
pub fn window_bases(
    coarse: &Raster<f32>,
    width: usize,
    height: usize,
    k: usize,
    max_disparity: usize,
) -> Vec<u16> {
    let (cw, ch) = (coarse.width(), coarse.height());
    let top = (max_disparity + 1).saturating_sub(k);
    // Each coarse pixel's window start, once (four full-size pixels share it).
    let mut coarse_bases = vec![0u16; cw * ch];
    coarse_bases
        .par_chunks_mut(cw)
        .enumerate()
        .for_each(|(cy, row)| {
            let rows: Vec<&[f32]> = (cy.saturating_sub(1)..=(cy + 1).min(ch - 1))
                .map(|qy| coarse.row(qy))
                .collect();
            for (cx, b) in row.iter_mut().enumerate() {
                let own = 2.0 * coarse.row(cy)[cx];
                let (mut lo, mut hi) = (own, own);
                for r in &rows {
                    for &v in &r[cx.saturating_sub(1)..=(cx + 1).min(cw - 1)] {
                        lo = lo.min(2.0 * v);
                        hi = hi.max(2.0 * v);
                    }
                }
                let centre = if hi - lo + 4.0 <= k as f32 {
                    0.5 * (lo + hi)
                } else {
                    own
                };
                let start = (centre - k as f32 / 2.0).round();
                *b = if start.is_finite() {
                    start.clamp(0.0, top as f32) as u16
                } else {
                    0
                };
            }
        });
    let mut bases = vec![0u16; width * height];
    bases
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, row)| {
            let src = &coarse_bases[(y / 2).min(ch - 1) * cw..][..cw];
            for (x, b) in row.iter_mut().enumerate() {
                *b = src[(x / 2).min(cw - 1)];
            }
        });
    bases
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduce_halves_and_keeps_flat_values() {
        let r = reduce(&Raster::filled(9, 6, 100u8));
        assert_eq!((r.width(), r.height()), (5, 3));
        assert!(r.pixels().iter().all(|&v| v == 100));
    }

    #[test]
    fn windows_cover_twice_the_coarse_disparity() {
        let coarse = Raster::filled(10, 10, 12.0f32);
        let b = window_bases(&coarse, 20, 20, 16, 63);
        assert!(b.iter().all(|&v| v as usize <= 24 && 24 < v as usize + 16));
        // Near the top of the range the window is clamped to stay inside it.
        let b = window_bases(&Raster::filled(4, 4, 31.5f32), 8, 8, 16, 63);
        assert!(b.iter().all(|&v| v == 48));
    }
}
