//! Sum-of-absolute-differences block cost (the thesis, Algorithm 1): the mean absolute grey-level
//! difference over a `(2r+1)²` block, on a 0–255 scale. Borders replicate; a candidate whose block
//! centre falls left of the right image gets [`OUTSIDE_COST`].

use super::cost::{CostRows, OUTSIDE_COST};
use crate::image::Raster;

/// Both views and the block half-size.
pub struct SadCost<'a> {
    left: &'a Raster<u8>,
    right: &'a Raster<u8>,
    radius: usize,
}

impl<'a> SadCost<'a> {
    /// A SAD cost over `(2·radius+1)²` blocks.
    pub fn new(left: &'a Raster<u8>, right: &'a Raster<u8>, radius: usize) -> Self {
        SadCost {
            left,
            right,
            radius,
        }
    }
}

impl CostRows for SadCost<'_> {
    fn width(&self) -> usize {
        self.left.width()
    }
    fn height(&self) -> usize {
        self.left.height()
    }

    fn row(&self, y: usize, bases: Option<&[u16]>, k: usize, out: &mut [u8]) {
        let (w, h, r) = (self.left.width(), self.left.height(), self.radius);
        let rows: Vec<usize> = (0..=2 * r)
            .map(|j| (y + j).saturating_sub(r).min(h - 1))
            .collect();
        let area = ((2 * r + 1) * (2 * r + 1)) as u32;
        let clampx = |x: isize| x.clamp(0, w as isize - 1) as usize;
        match bases {
            None => {
                // One disparity at a time: absolute differences summed down the block's rows, then
                // a running sum along the row. O(width · rows) per disparity, vectorisable over x.
                let mut column = vec![0u32; w];
                for d in 0..k {
                    column.fill(0);
                    for &yy in &rows {
                        let (l, rr) = (self.left.row(yy), self.right.row(yy));
                        for x in 0..w {
                            let xr = x.saturating_sub(d);
                            column[x] += l[x].abs_diff(rr[xr]) as u32;
                        }
                    }
                    let mut sum: u32 = (0..=2 * r)
                        .map(|i| column[clampx(i as isize - r as isize)])
                        .sum();
                    for x in 0..w {
                        out[x * k + d] = if x >= d {
                            (sum / area).min(255) as u8
                        } else {
                            OUTSIDE_COST
                        };
                        let add = column[clampx(x as isize + r as isize + 1)];
                        let sub = column[clampx(x as isize - r as isize)];
                        sum = sum + add - sub;
                    }
                }
            }
            Some(bases) => {
                for x in 0..w {
                    for i in 0..k {
                        let d = bases[x] as usize + i;
                        out[x * k + i] = if x < d {
                            OUTSIDE_COST
                        } else {
                            let mut sum = 0u32;
                            for &yy in &rows {
                                let (l, rr) = (self.left.row(yy), self.right.row(yy));
                                for dx in -(r as isize)..=r as isize {
                                    let xl = clampx(x as isize + dx);
                                    let xr = clampx(x as isize + dx - d as isize);
                                    sum += l[xl].abs_diff(rr[xr]) as u32;
                                }
                            }
                            (sum / area).min(255) as u8
                        };
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sad_is_zero_at_the_true_shift_and_agrees_with_and_without_bases() {
        let w = 30;
        let left = Raster::from_fn(w, 7, |x, y| ((x * 31 + y * 17) % 29 * 8) as u8);
        let right = Raster::from_fn(w, 7, |x, y| *left.get((x + 2).min(w - 1), y));
        let cost = SadCost::new(&left, &right, 1);
        let k = 5;
        let mut full = vec![0u8; w * k];
        cost.row(3, None, k, &mut full);
        for x in 4..25 {
            assert_eq!(full[x * k + 2], 0, "x = {x}");
            assert!(full[x * k] > 0);
        }
        let zeros = vec![0u16; w];
        let mut windowed = vec![0u8; w * k];
        cost.row(3, Some(&zeros), k, &mut windowed);
        // The two code paths clamp the block at the borders the same way except where the right
        // block is cut off (x − r − d < 0); compare away from there.
        for x in 8..w - 2 {
            assert_eq!(
                full[x * k..x * k + k],
                windowed[x * k..x * k + k],
                "x = {x}"
            );
        }
    }
}
