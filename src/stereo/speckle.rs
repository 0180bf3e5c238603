//! Speckle removal: small connected regions of similar disparity are taken for mismatches.
//!
//! Regions are labelled with union–find, in horizontal strips on all threads, and counted there;
//! then the strips are joined across their borders, where only the regions that cross a border
//! move their counts (few, and the only serial work). Two neighbours belong together when both
//! are valid and their disparities differ by at most the range; the relation is symmetric, so the
//! regions are the connected components of one graph and come out the same as a flood fill's,
//! whatever the order.

use rayon::prelude::*;

use super::refine::PixelState;
use crate::image::Raster;

/// Marks as [`PixelState::Mismatch`] (and its disparity NaN) every 4-connected region of valid
/// pixels (neighbours differing by at most `range`) smaller than `max_size` pixels. `state` holds
/// one entry per pixel, row by row; nothing is removed when it does not, or for an image of more
/// than 2³² pixels (whose labels would not fit `u32`).
pub fn remove_speckles(
    disparity: &mut Raster<f32>,
    state: &mut [PixelState],
    max_size: usize,
    range: f32,
) {
    let (w, h) = (disparity.width(), disparity.height());
    let n = w * h;
    if max_size == 0 || n == 0 || state.len() != n || n > u32::MAX as usize {
        return;
    }
    let d = disparity.pixels();
    let joined = |p: usize, q: usize| {
        state[p] == PixelState::Valid
            && state[q] == PixelState::Valid
            && (d[q] - d[p]).abs() <= range
    };
    let mut parent: Vec<u32> = (0..n as u32).collect();
    // Several strips a thread, so that uneven strips still share the work.
    let strip_rows = h.div_ceil(4 * rayon::current_num_threads()).max(1);
    // Each strip's own regions, each pixel pointing at its region's first pixel in the strip,
    // and each region's size in the strip, at that pixel.
    let mut size = vec![0u32; n];
    parent
        .par_chunks_mut(strip_rows * w)
        .zip(size.par_chunks_mut(strip_rows * w))
        .enumerate()
        .for_each(|(s, (strip, size))| {
            let mut forest = Forest {
                parent: strip,
                offset: s * strip_rows * w,
            };
            let rows = forest.parent.len() / w;
            for y in 0..rows {
                // The first pixel of the current run of joined pixels along the row.
                let mut run_start = 0;
                for x in 0..w {
                    let i = y * w + x;
                    let p = forest.offset + i;
                    // A pixel joined to its left neighbour is untouched so far (its upper
                    // neighbour comes next): it hangs under its run's first pixel directly,
                    // without the two searches of a union. That pixel's index is smaller, so
                    // every root stays the smallest index of its set.
                    if x > 0 && joined(p - 1, p) {
                        forest.parent[i] = (forest.offset + run_start) as u32;
                    } else {
                        run_start = i;
                    }
                    if y > 0 && joined(p - w, p) {
                        forest.union(i - w, i);
                    }
                }
            }
            // Every pixel's parent has a smaller index than the pixel (until it is a root), so
            // one pass in ascending order leaves each pointing straight at its root.
            for i in 0..forest.parent.len() {
                let root = forest.parent[forest.parent[i] as usize - forest.offset];
                forest.parent[i] = root;
                size[root as usize - forest.offset] += 1;
            }
        });
    // Regions that cross a strip border: the later strip's root hangs under the earlier one's
    // (the smaller index), and its count moves there once every border is joined.
    let mut forest = Forest {
        parent: &mut parent,
        offset: 0,
    };
    let mut merged = Vec::new();
    for y in (strip_rows..h).step_by(strip_rows) {
        for x in 0..w {
            let q = y * w + x;
            if joined(q - w, q) {
                if let Some(joined_root) = forest.union(q - w, q) {
                    merged.push(joined_root);
                }
            }
        }
    }
    // A strip root that was joined is no root any more, so its count is its strip's alone; it
    // is pointed straight at its region's root.
    for &r in &merged {
        let root = forest.find(r);
        size[root] += size[r];
        forest.parent[r] = root as u32;
    }
    // A pixel's region: its strip root, or that root's root (read only).
    let parent = &parent;
    let region = |i: usize| {
        let mut r = parent[i] as usize;
        while parent[r] as usize != r {
            r = parent[r] as usize;
        }
        r
    };
    disparity
        .pixels_mut()
        .par_iter_mut()
        .zip(state.par_iter_mut())
        .enumerate()
        .for_each(|(i, (d, s))| {
            if *s == PixelState::Valid && (size[region(i)] as usize) < max_size {
                *s = PixelState::Mismatch;
                *d = f32::NAN;
            }
        });
}

/// Union–find over a run of pixels `offset..offset + parent.len()`; `parent` holds image-wide
/// indices, and every index a method takes or returns is relative to `offset`.
struct Forest<'a> {
    parent: &'a mut [u32],
    offset: usize,
}

impl Forest<'_> {
    /// The root of `i`, halving the path on the way.
    fn find(&mut self, mut i: usize) -> usize {
        loop {
            let p = self.parent[i] as usize - self.offset;
            if p == i {
                return i;
            }
            let grandparent = self.parent[p];
            self.parent[i] = grandparent;
            i = grandparent as usize - self.offset;
        }
    }

    /// Joins the sets of `a` and `b` under the smaller root index; the root that stopped being
    /// one, if the two were apart.
    fn union(&mut self, a: usize, b: usize) -> Option<usize> {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra == rb {
            return None;
        }
        let (low, high) = (ra.min(rb), ra.max(rb));
        self.parent[high] = (low + self.offset) as u32;
        Some(high)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flood fill the union–find replaces, written plainly.
    fn flood_fill_speckles(d: &mut Raster<f32>, state: &mut [PixelState], max: usize, range: f32) {
        let (w, h) = (d.width(), d.height());
        let v = d.pixels().to_vec();
        let mut seen = vec![false; w * h];
        for start in 0..w * h {
            if seen[start] || state[start] != PixelState::Valid {
                continue;
            }
            let (mut stack, mut region) = (vec![start], Vec::new());
            seen[start] = true;
            while let Some(p) = stack.pop() {
                region.push(p);
                let (x, y) = (p % w, p / w);
                let neighbours = [
                    (x > 0).then(|| p - 1),
                    (x + 1 < w).then(|| p + 1),
                    (y > 0).then(|| p - w),
                    (y + 1 < h).then(|| p + w),
                ];
                for q in neighbours.into_iter().flatten() {
                    if !seen[q] && state[q] == PixelState::Valid && (v[q] - v[p]).abs() <= range {
                        seen[q] = true;
                        stack.push(q);
                    }
                }
            }
            if region.len() < max {
                for p in region {
                    state[p] = PixelState::Mismatch;
                    d.pixels_mut()[p] = f32::NAN;
                }
            }
        }
    }

    #[test]
    fn small_regions_are_removed_and_large_ones_kept() {
        let mut d = Raster::from_fn(20, 20, |x, y| {
            if (8..10).contains(&x) && (8..10).contains(&y) {
                30.0
            } else {
                5.0
            }
        });
        let mut st = vec![PixelState::Valid; 400];
        remove_speckles(&mut d, &mut st, 10, 1.0);
        assert!(d.get(8, 8).is_nan());
        assert_eq!(st[8 * 20 + 9], PixelState::Mismatch);
        assert_eq!(*d.get(0, 0), 5.0);
        assert_eq!(st.iter().filter(|s| **s == PixelState::Mismatch).count(), 4);
    }

    #[test]
    fn regions_match_a_flood_fill_across_strips() {
        // Random blobs of a few disparity levels with holes, on sizes that split into uneven
        // strips; a one-pixel-wide line through every strip included.
        let mut rng = crate::mesh::surfaces::XorShift(11);
        for (w, h) in [(1, 1), (1, 37), (37, 1), (64, 48), (97, 131)] {
            for max in [1, 5, 40] {
                let mut d = Raster::from_fn(w, h, |_, _| rng.below(4) as f32 * 0.7);
                let mut st: Vec<PixelState> = (0..w * h)
                    .map(|_| {
                        if rng.below(7) == 0 {
                            PixelState::Occluded
                        } else {
                            PixelState::Valid
                        }
                    })
                    .collect();
                if w > 8 && h > 8 {
                    for y in 0..h {
                        *d.get_mut(3, y) = 50.0;
                        st[y * w + 3] = PixelState::Valid;
                    }
                }
                let (mut d2, mut st2) = (d.clone(), st.clone());
                remove_speckles(&mut d, &mut st, max, 1.0);
                flood_fill_speckles(&mut d2, &mut st2, max, 1.0);
                assert_eq!(st, st2, "{w}x{h}, max {max}");
                let same = d
                    .pixels()
                    .iter()
                    .zip(d2.pixels())
                    .all(|(a, b)| a == b || (a.is_nan() && b.is_nan()));
                assert!(same, "{w}x{h}, max {max}");
            }
        }
    }
}
