//! Census-transform matching cost: each pixel becomes a bit string saying which neighbours are
//! darker than it; the cost of a match is the Hamming distance of the two strings. It depends only
//! on the order of grey levels, so exposure and lighting changes between the views do not affect it.

use rayon::prelude::*;

use super::buffer;
use super::cost::{inside_right_view, CostRows, OUTSIDE_COST};
use crate::image::Raster;

/// Census transforms of both views and the scale that maps Hamming distances onto 0–255.
pub struct CensusCost {
    width: usize,
    height: usize,
    left: Vec<u64>,
    /// The right view's rows stored mirrored, so that the disparity loop reads memory forwards.
    right_mirrored: Vec<u64>,
    /// `cost = (hamming × scale) >> 8`.
    scale: u16,
}

/// Census transform with a `(2rx+1)×(2ry+1)` window (at most 63 neighbours); borders replicate.
/// Neighbour `t` (row-major, the centre skipped) is bit `count − 1 − t` of a pixel's string.
pub fn census_transform(image: &Raster<u8>, rx: usize, ry: usize) -> Vec<u64> {
    census_transform_into(image, rx, ry, Vec::new())
}

/// [`census_transform`] into `spare`'s memory when it holds enough (see [`buffer::reuse`]).
pub fn census_transform_into(
    image: &Raster<u8>,
    rx: usize,
    ry: usize,
    spare: Vec<u64>,
) -> Vec<u64> {
    let (w, h) = (image.width(), image.height());
    // Rows padded by rx replicated pixels on each side, so the inner loop has no bounds logic.
    let pw = w + 2 * rx;
    let mut padded = vec![0u8; pw * h];
    for y in 0..h {
        let row = image.row(y);
        let dst = &mut padded[y * pw..(y + 1) * pw];
        dst[rx..rx + w].copy_from_slice(row);
        let (first, last) = (row[0], row[w - 1]);
        dst[..rx].fill(first);
        dst[rx + w..].fill(last);
    }
    let window = Window {
        rx,
        ry,
        neighbours: (0..=2 * ry)
            .flat_map(|j| (0..=2 * rx).map(move |i| (j, i)))
            .filter(|&(j, i)| (j, i) != (ry, rx))
            .collect(),
    };
    debug_assert!(window.neighbours.len() <= 64);
    let padded = Padded {
        pixels: &padded,
        width: pw,
        height: h,
    };
    // Every row is written whole (`census_row_body` clears it first).
    let mut out = buffer::reuse(spare, w * h);
    out.par_chunks_mut(w).enumerate().for_each_init(
        || vec![0u8; w],
        |byte, (y, bits)| census_row_transform(&padded, &window, y, byte, bits),
    );
    out
}

/// A census window: half-sizes and the neighbours' offsets `(row, column)` from its top-left
/// corner, in bit order.
struct Window {
    rx: usize,
    ry: usize,
    neighbours: Vec<(usize, usize)>,
}

/// An image whose rows are padded by `rx` replicated pixels on each side.
struct Padded<'a> {
    pixels: &'a [u8],
    width: usize,
    height: usize,
}

crate::avx2_variant!(fn census_row_transform<'a>(padded: &'a Padded<'a>, window: &'a Window, y: usize, byte: &'a mut [u8], bits: &'a mut [u64]) => census_row_body);

#[inline(always)]
fn census_row_body(
    padded: &Padded<'_>,
    window: &Window,
    y: usize,
    byte: &mut [u8],
    bits: &mut [u64],
) {
    let (w, pw, h) = (bits.len(), padded.width, padded.height);
    let (rx, ry) = (window.rx, window.ry);
    let centre = &padded.pixels[y * pw + rx..y * pw + rx + w];
    let count = window.neighbours.len();
    // Eight neighbours at a time into a byte per pixel (32 pixels per AVX2 instruction), then
    // each byte into its place in the 64-bit strings: ⌈count / 8⌉ passes over u64 lanes instead
    // of one per neighbour.
    bits.fill(0);
    for (g, group) in window.neighbours.chunks(8).enumerate() {
        byte.fill(0);
        for &(j, i) in group {
            let yy = (y + j).saturating_sub(ry).min(h - 1);
            let neighbour = &padded.pixels[yy * pw + i..yy * pw + i + w];
            for ((b, &n), &c) in byte.iter_mut().zip(neighbour).zip(centre) {
                *b = (*b << 1) | (n < c) as u8;
            }
        }
        let shift = count - 8 * g - group.len();
        for (b, &v) in bits.iter_mut().zip(&*byte) {
            *b |= (v as u64) << shift;
        }
    }
}

impl CensusCost {
    /// Transforms both views (same size) with the given window half-sizes.
    pub fn new(left: &Raster<u8>, right: &Raster<u8>, rx: usize, ry: usize) -> Self {
        Self::in_buffers(left, right, rx, ry, [Vec::new(), Vec::new()])
    }

    /// [`CensusCost::new`] in the memory of `spare` (the left and the right view's transforms,
    /// as [`CensusCost::into_buffers`] gives them back).
    pub fn in_buffers(
        left: &Raster<u8>,
        right: &Raster<u8>,
        rx: usize,
        ry: usize,
        spare: [Vec<u64>; 2],
    ) -> Self {
        let (w, h) = (left.width(), left.height());
        let bits = ((2 * rx + 1) * (2 * ry + 1) - 1).max(1);
        let [spare_left, spare_right] = spare;
        let mut right_mirrored = census_transform_into(right, rx, ry, spare_right);
        for row in right_mirrored.chunks_mut(w) {
            row.reverse();
        }
        CensusCost {
            width: w,
            height: h,
            left: census_transform_into(left, rx, ry, spare_left),
            right_mirrored,
            scale: (255 * 256 / bits) as u16,
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        (self.left.len() + self.right_mirrored.len()) * 8
    }

    /// The two transforms' memory, for [`CensusCost::in_buffers`].
    pub fn into_buffers(self) -> [Vec<u64>; 2] {
        [self.left, self.right_mirrored]
    }
}

impl CostRows for CensusCost {
    fn width(&self) -> usize {
        self.width
    }
    fn height(&self) -> usize {
        self.height
    }

    fn row(&self, y: usize, bases: Option<&[u16]>, k: usize, out: &mut [u8]) {
        let w = self.width;
        let left = &self.left[y * w..(y + 1) * w];
        let mirrored = &self.right_mirrored[y * w..(y + 1) * w];
        census_row_fast(left, mirrored, bases, k, self.scale, out);
    }
}

crate::avx2_variant!(fn census_row_fast<'a>(left: &'a [u64], mirrored: &'a [u64], bases: Option<&'a [u16]>, k: usize, scale: u16, out: &'a mut [u8]) => census_row);

#[inline(always)]
fn census_row(
    left: &[u64],
    mirrored: &[u64],
    bases: Option<&[u16]>,
    k: usize,
    scale: u16,
    out: &mut [u8],
) {
    let w = left.len();
    for (x, (&cl, costs)) in left.iter().zip(out.chunks_exact_mut(k)).enumerate() {
        let base = bases.map_or(0, |b| b[x] as usize);
        // Disparity d = base + i matches right pixel x − d, i.e. mirrored index w − 1 − x + d.
        let valid = inside_right_view(x, base, k);
        if valid > 0 {
            let start = w - 1 - x + base;
            let right = &mirrored[start..start + valid];
            for (c, &cr) in costs[..valid].iter_mut().zip(right) {
                *c = (((cl ^ cr).count_ones() as u16 * scale) >> 8) as u8;
            }
        }
        // Only near the left border: an empty `fill` is still a call to `memset` per pixel.
        if valid < k {
            costs[valid..].fill(OUTSIDE_COST);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn census_bits_say_which_neighbours_are_darker() {
        // 3x3 with the centre 5: neighbours below 5 set their bit (row-major, centre skipped).
        let img = Raster::from_vec(3, 3, vec![1, 9, 1, 9, 5, 9, 1, 9, 1]);
        let c = census_transform(&img, 1, 1);
        assert_eq!(c[4], 0b1010_0101);
    }

    #[test]
    fn bit_strings_match_a_pixel_by_pixel_transform_for_every_window_shape() {
        let (w, h) = (19, 11);
        let img = Raster::from_fn(w, h, |x, y| ((x * 37 + y * 101 + x * y) % 251) as u8);
        for (rx, ry) in [(0, 1), (1, 0), (1, 1), (2, 1), (2, 2), (3, 3), (4, 3)] {
            let fast = census_transform(&img, rx, ry);
            for y in 0..h {
                for x in 0..w {
                    // Neighbours in row-major order, each shifted in below the ones before.
                    let mut bits = 0u64;
                    let at = |dx: isize, dy: isize| {
                        let xx = (x as isize + dx).clamp(0, w as isize - 1) as usize;
                        let yy = (y as isize + dy).clamp(0, h as isize - 1) as usize;
                        *img.get(xx, yy)
                    };
                    for dy in -(ry as isize)..=ry as isize {
                        for dx in -(rx as isize)..=rx as isize {
                            if (dx, dy) != (0, 0) {
                                bits = bits << 1 | (at(dx, dy) < at(0, 0)) as u64;
                            }
                        }
                    }
                    assert_eq!(fast[y * w + x], bits, "window {rx}x{ry}, pixel ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn cost_is_zero_at_the_true_shift_and_scaled_hamming_elsewhere() {
        let w = 40;
        let left = Raster::from_fn(w, 5, |x, y| ((x * 37 + y * 11) % 23 * 10) as u8);
        let right = Raster::from_fn(w, 5, |x, y| *left.get((x + 3).min(w - 1), y));
        let cost = CensusCost::new(&left, &right, 1, 1);
        let k = 8;
        let mut row = vec![0u8; w * k];
        cost.row(2, None, k, &mut row);
        for x in 10..30 {
            assert_eq!(row[x * k + 3], 0, "x = {x}");
        }
        assert_eq!(
            &row[..k],
            &[
                row[0],
                OUTSIDE_COST,
                OUTSIDE_COST,
                OUTSIDE_COST,
                OUTSIDE_COST,
                OUTSIDE_COST,
                OUTSIDE_COST,
                OUTSIDE_COST
            ]
        );
        // With bases the window moves: base 2, index 1 is disparity 3.
        let bases = vec![2u16; w];
        cost.row(2, Some(&bases), 4, &mut row[..w * 4]);
        for x in 10..30 {
            assert_eq!(row[x * 4 + 1], 0);
        }
    }
}
