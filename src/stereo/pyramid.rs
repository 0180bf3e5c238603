//! Coarse-to-fine search (the thesis' Gaussian pyramid, §3.2.1): the pair is reduced to half size,
//! matched there over half the range, and each full-size pixel then searches only a window of
//! disparities around twice the coarse answer.

use rayon::prelude::*;

use crate::image::Raster;

/// Gaussian reduce: 5-tap binomial filter `[1 4 6 4 1]/16` in x and y (borders replicated), then
/// every second pixel.
pub fn reduce(image: &Raster<u8>) -> Raster<u8> {
    let (w, h) = (image.width(), image.height());
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    // Horizontal pass on every row, at the coarse columns only. Sums fit `u16` (at most
    // 16 · 255 here and 256 · 255 + 128 after the vertical pass), so both passes are plain loops
    // over whole rows the compiler vectorises: the row is split into its even and odd pixels,
    // replicated two pixels past each end, and coarse column `cx` is
    // `even[cx] + 4·odd[cx] + 6·even[cx+1] + 4·odd[cx+1] + even[cx+2]` (padded indices).
    let mut tmp = vec![0u16; cw * h];
    tmp.par_chunks_mut(cw).enumerate().for_each_init(
        || (vec![0u16; cw + 2], vec![0u16; cw + 2]),
        |(even, odd), (y, out)| {
            let row = image.row(y);
            // Padded pixel i is image pixel clamp(i − 2): even[j] = pixel 2j − 2, odd[j] = 2j − 1.
            let at = |i: usize| row[i.saturating_sub(2).min(w - 1)] as u16;
            for (j, (e, o)) in even.iter_mut().zip(odd.iter_mut()).enumerate() {
                *e = at(2 * j);
                *o = at(2 * j + 1);
            }
            for (cx, o) in out.iter_mut().enumerate() {
                *o = even[cx] + 4 * odd[cx] + 6 * even[cx + 1] + 4 * odd[cx + 1] + even[cx + 2];
            }
        },
    );
    let mut out = vec![0u8; cw * ch];
    out.par_chunks_mut(cw).enumerate().for_each(|(cy, row)| {
        let source = |j: usize| {
            let y = (2 * cy + j).saturating_sub(2).min(h - 1);
            &tmp[y * cw..(y + 1) * cw]
        };
        let (a, b, c, d, e) = (source(0), source(1), source(2), source(3), source(4));
        for (i, o) in row.iter_mut().enumerate() {
            let s = a[i] + 4 * b[i] + 6 * c[i] + 4 * d[i] + e[i];
            *o = ((s as u32 + 128) >> 8) as u8;
        }
    });
    Raster::from_vec(cw, ch, out)
}

/// Per-pixel window starts for a `width × height` level from the coarse level's dense disparity:
/// each window of `k` disparities (clamped to `0..=max_disparity`) covers the disparities of the
/// 3×3 coarse neighbourhood when they fit in it, else centres on the pixel's own coarse value.
/// `coarse` must be the half-size level of `width × height` (`width.div_ceil(2)` wide).
pub fn window_bases(
    coarse: &Raster<f32>,
    width: usize,
    height: usize,
    k: usize,
    max_disparity: usize,
) -> Vec<u16> {
    let (cw, ch) = (coarse.width(), coarse.height());
    debug_assert_eq!((cw, ch), (width.div_ceil(2), height.div_ceil(2)));
    let top = (max_disparity + 1).saturating_sub(k);
    // The 3×3 neighbourhood's extremes as the extremes over three rows of each row's extremes
    // over three columns, each a plain pass over a row (`f32::min`/`max` skip NaN, so the order
    // does not matter).
    let across = |row: &[f32], pick: fn(f32, f32) -> f32| -> Vec<f32> {
        let mut out = row.to_vec();
        for (o, pair) in out[1..].iter_mut().zip(row.windows(2)) {
            *o = pick(pick(*o, pair[0]), pair[1]);
        }
        for (o, &right) in out.iter_mut().zip(&row[1..]) {
            *o = pick(*o, right);
        }
        out
    };
    let (row_lo, row_hi): (Vec<Vec<f32>>, Vec<Vec<f32>>) = (0..ch)
        .into_par_iter()
        .map(|cy| {
            (
                across(coarse.row(cy), f32::min),
                across(coarse.row(cy), f32::max),
            )
        })
        .unzip();
    // Each coarse pixel's window start, once (four full-size pixels share it).
    let mut coarse_bases = vec![0u16; cw * ch];
    coarse_bases
        .par_chunks_mut(cw)
        .enumerate()
        .for_each(|(cy, row)| {
            let (up, down) = (cy.saturating_sub(1), (cy + 1).min(ch - 1));
            let lo = row_lo[up].iter().zip(&row_lo[cy]).zip(&row_lo[down]);
            let hi = row_hi[up].iter().zip(&row_hi[cy]).zip(&row_hi[down]);
            for (((b, &own), ((&l0, &l1), &l2)), ((&h0, &h1), &h2)) in
                row.iter_mut().zip(coarse.row(cy)).zip(lo).zip(hi)
            {
                let (own, lo, hi) = (
                    2.0 * own,
                    2.0 * l0.min(l1).min(l2),
                    2.0 * h0.max(h1).max(h2),
                );
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

    #[test]
    fn reduce_is_the_binomial_filter_with_replicated_borders() {
        use crate::mesh::surfaces::XorShift;
        let mut rng = XorShift(0x9e11);
        for (w, h) in [(1usize, 1usize), (2, 3), (13, 9), (16, 7)] {
            let image = Raster::from_fn(w, h, |_, _| rng.below(256) as u8);
            let taps = [1u32, 4, 6, 4, 1];
            let at = |x: isize, y: isize| {
                let (x, y) = (x.clamp(0, w as isize - 1), y.clamp(0, h as isize - 1));
                *image.get(x as usize, y as usize) as u32
            };
            let r = reduce(&image);
            assert_eq!((r.width(), r.height()), (w.div_ceil(2), h.div_ceil(2)));
            for cy in 0..r.height() {
                for cx in 0..r.width() {
                    let mut s = 0;
                    for (j, tj) in taps.iter().enumerate() {
                        for (i, ti) in taps.iter().enumerate() {
                            let (x, y) =
                                (2 * cx as isize + i as isize, 2 * cy as isize + j as isize);
                            s += tj * ti * at(x - 2, y - 2);
                        }
                    }
                    assert_eq!(
                        *r.get(cx, cy) as u32,
                        (s + 128) / 256,
                        "{w}x{h} at {cx},{cy}"
                    );
                }
            }
        }
    }

    #[test]
    fn window_starts_follow_the_plain_neighbourhood_rule() {
        use crate::mesh::surfaces::XorShift;
        let mut rng = XorShift(0xba5e);
        let (w, h, k, max) = (23usize, 15usize, 16usize, 63usize);
        // Mostly smooth disparities with jumps, and a few holes (NaN), which the rule skips.
        let coarse = Raster::from_fn(w.div_ceil(2), h.div_ceil(2), |x, _| match rng.below(20) {
            0 => f32::NAN,
            1 => rng.below(32) as f32,
            _ => 10.0 + x as f32 * 0.5,
        });
        let bases = window_bases(&coarse, w, h, k, max);
        let (cw, ch) = (coarse.width(), coarse.height());
        for y in 0..h {
            for x in 0..w {
                let (cx, cy) = (x / 2, y / 2);
                let own = 2.0 * *coarse.get(cx, cy);
                let (mut lo, mut hi) = (own, own);
                for qy in cy.saturating_sub(1)..=(cy + 1).min(ch - 1) {
                    for qx in cx.saturating_sub(1)..=(cx + 1).min(cw - 1) {
                        lo = lo.min(2.0 * *coarse.get(qx, qy));
                        hi = hi.max(2.0 * *coarse.get(qx, qy));
                    }
                }
                let centre = if hi - lo + 4.0 <= k as f32 {
                    0.5 * (lo + hi)
                } else {
                    own
                };
                let start = (centre - k as f32 / 2.0).round();
                let expected = if start.is_finite() {
                    start.clamp(0.0, (max + 1 - k) as f32) as u16
                } else {
                    0
                };
                assert_eq!(bases[y * w + x], expected, "at {x},{y}");
            }
        }
    }
}
