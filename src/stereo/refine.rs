//! From aggregated costs to a disparity map: winner-takes-all, the uncertainty term `U_p`
//! (eq. 3.5) as a confidence, sub-pixel refinement, uniqueness and the left/right consistency
//! check; speckle removal ([`remove_speckles`]) lives in [`super::speckle`].

use rayon::prelude::*;

use super::options::Subpixel;
use super::sgm::Aggregated;
use crate::image::Raster;

/// Why a pixel has no estimate (or that it has one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum PixelState {
    /// Estimate kept.
    Valid = 0,
    /// The L/R check says the pixel is hidden in the right view (a nearer surface covers it).
    Occluded = 1,
    /// Ambiguous or inconsistent: uniqueness, L/R mismatch, or a speckle.
    Mismatch = 2,
}

/// Winner, validity and confidence per pixel.
pub struct Decision {
    /// Disparity in pixels, NaN where invalid.
    pub disparity: Raster<f32>,
    /// Per pixel state.
    pub state: Vec<PixelState>,
    /// Confidence in [0, 1].
    pub confidence: Raster<f32>,
}

/// Settings of [`decide`].
#[derive(Debug, Clone, Copy)]
pub struct DecideOptions {
    /// Sub-pixel method.
    pub subpixel: Subpixel,
    /// Uniqueness margin, percent (0 = off).
    pub uniqueness: u32,
    /// L/R tolerance in pixels, `None` = no check.
    pub lr_max_diff: Option<u32>,
    /// Cost units that make `U_p` = this × paths map to confidence 0.5.
    pub confidence_unit: f32,
}

/// Sub-pixel offset in [−0.5, 0.5] from the costs at d−1, d, d+1 (`c0 ≤ cm, cp`).
///
/// Flat or degenerate curves (denominator ≈ 0) give 0, never a division by zero.
pub fn subpixel_offset(method: Subpixel, cm: f32, c0: f32, cp: f32) -> f32 {
    let off = match method {
        Subpixel::None => 0.0,
        Subpixel::Parabola => {
            let denom = cm + cp - 2.0 * c0;
            if denom <= 1e-6 {
                0.0
            } else {
                (cm - cp) / (2.0 * denom)
            }
        }
        Subpixel::Equiangular => {
            let denom = cm.max(cp) - c0;
            if denom <= 1e-6 {
                0.0
            } else {
                (cm - cp) / (2.0 * denom)
            }
        }
    };
    if off.is_finite() {
        off.clamp(-0.5, 0.5)
    } else {
        0.0
    }
}

/// Picks each pixel's winner in `agg` (window `bases[p]..bases[p]+k`), refines and checks it.
pub fn decide(agg: &Aggregated, bases: Option<&[u16]>, opts: &DecideOptions) -> Decision {
    let (w, h) = (agg.width, agg.height);
    let mut disparity = vec![f32::NAN; w * h];
    let mut state = vec![PixelState::Valid; w * h];
    let mut confidence = vec![0f32; w * h];
    let unit = opts.confidence_unit.max(1e-3) * agg.paths as f32;
    disparity
        .par_chunks_mut(w)
        .zip(state.par_chunks_mut(w))
        .zip(confidence.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, ((disp, st), conf))| {
            let row = RowInput {
                agg,
                bases,
                opts,
                unit,
                y,
            };
            decide_row_fast(&row, disp, st, conf);
        });
    Decision {
        disparity: Raster::from_vec(w, h, disparity),
        state,
        confidence: Raster::from_vec(w, h, confidence),
    }
}

struct RowInput<'a> {
    agg: &'a Aggregated,
    bases: Option<&'a [u16]>,
    opts: &'a DecideOptions,
    unit: f32,
    y: usize,
}

crate::avx2_variant!(fn decide_row_fast<'a, 'b>(input: &'b RowInput<'a>, disp: &'b mut [f32], st: &'b mut [PixelState], conf: &'b mut [f32]) => decide_row);

/// Winner, sub-pixel, uniqueness and L/R check of one row.
#[inline(always)]
fn decide_row(input: &RowInput<'_>, disp: &mut [f32], st: &mut [PixelState], conf: &mut [f32]) {
    let RowInput {
        agg,
        bases,
        opts,
        unit,
        y,
    } = *input;
    let (w, k) = (agg.width, agg.k);
    let s_row = &agg.s[y * w * k..(y + 1) * w * k];
    let bases = bases.map(|b| &b[y * w..(y + 1) * w]);
    // Integer winners of the left view, and of the right view from the same volume:
    // the right pixel xr = x − d sees left pixel x at disparity d. Costs and disparities are
    // packed as `cost << 16 | d` so that one `min` keeps the cheapest disparity and, on ties, the
    // smallest (what a first-index search would find). The right row is stored mirrored
    // (`mirrored[w − 1 − xr]`) so that a pixel's disparities update it in ascending order: a
    // plain loop the compiler vectorises.
    let mut best_left = vec![0u32; w];
    let mut mirrored = vec![u32::MAX; w];
    for x in 0..w {
        let s = &s_row[x * k..(x + 1) * k];
        let base = bases.map_or(0, |b| b[x] as usize);
        let (bv, bi) = first_min(s);
        // Right view: disparities d = base + i ≤ x only, i.e. right pixels x − base − i.
        if x >= base {
            let valid = (x - base + 1).min(k);
            let m0 = w - 1 - (x - base);
            update_right(&mut mirrored[m0..m0 + valid], &s[..valid], base as u32);
        }
        best_left[x] = (base + bi) as u32;
        // U_p here, its confidence after the loop (divisions vectorise there, not here).
        conf[x] = bv.saturating_sub(agg.min_sum[y * w + x]) as f32;
        // Unique when every disparity not adjacent to the winner costs at least
        // bv / (1 − uniqueness): compare the smallest of them once.
        if opts.uniqueness > 0 && (bi >= 2 || bi + 2 < k) {
            let other = min_away_from(s, bi);
            if (other as u64) * (100 - opts.uniqueness as u64) < bv as u64 * 100 {
                st[x] = PixelState::Mismatch;
                continue;
            }
        }
        let off = if bi > 0 && bi + 1 < k {
            subpixel_offset(opts.subpixel, s[bi - 1] as f32, bv as f32, s[bi + 1] as f32)
        } else {
            0.0
        };
        disp[x] = (base + bi) as f32 + off;
    }
    for c in conf.iter_mut() {
        *c = 1.0 / (1.0 + *c / unit);
    }
    if let Some(tol) = opts.lr_max_diff {
        for x in 0..w {
            if st[x] != PixelState::Valid {
                continue;
            }
            let d = best_left[x] as usize;
            if d > x || (mirrored[w - 1 - (x - d)] & 0xFFFF).abs_diff(d as u32) > tol {
                st[x] = PixelState::Mismatch;
            }
        }
        // Hirschmüller's rule: a failed pixel is occluded when no disparity at all would
        // pass the check (its true match is hidden), and a mismatch otherwise.
        // Pixel x at disparity d = x − xr passes when |best(xr) − d| ≤ tol, i.e. when x lies
        // within tol of xr + best(xr): mark those x once per right pixel instead of trying
        // every disparity of every failed pixel. The marks are counted as +1 at the start of
        // each interval and −1 after its end, so a running sum says whether x is covered.
        let top = bases.map_or(k, |b| b.iter().map(|&v| v as usize + k).max().unwrap_or(k));
        let tol = tol as usize;
        let mut starts = vec![0i32; w + 1];
        for (xr, &packed) in mirrored.iter().rev().enumerate() {
            if packed == u32::MAX {
                continue;
            }
            let t = xr + (packed & 0xFFFF) as usize;
            let lo = t.saturating_sub(tol).max(xr);
            let hi = (t + tol).min(xr + top - 1).min(w - 1);
            if lo <= hi {
                starts[lo] += 1;
                starts[hi + 1] -= 1;
            }
        }
        let mut covering = 0i32;
        for x in 0..w {
            covering += starts[x];
            if st[x] != PixelState::Valid && covering == 0 {
                st[x] = PixelState::Occluded;
            }
        }
    }
    for x in 0..w {
        if st[x] != PixelState::Valid {
            disp[x] = f32::NAN;
        }
    }
}

/// `mirrored[i] = min(mirrored[i], costs[i] << 16 | (base + i))`: one pixel's costs offered to
/// the right-view pixels its disparities reach (see [`decide_row`]).
#[inline(always)]
fn update_right(mirrored: &mut [u32], costs: &[u16], base: u32) {
    for ((r, &v), i) in mirrored.iter_mut().zip(costs).zip(0u32..) {
        *r = (*r).min((v as u32) << 16 | (base + i));
    }
}

/// The smallest cost of `s` more than one disparity away from index `winner` (`u16::MAX` when
/// there is none). One pass over the whole window, the winner and its neighbours masked out,
/// instead of two slices of varying length (which the compiler leaves scalar).
#[inline(always)]
fn min_away_from(s: &[u16], winner: usize) -> u16 {
    // `i − (winner − 1)` in wrapping arithmetic is 0, 1, 2 for the three masked indices and
    // larger for every other (including winner = 0, where it wraps to i + 1).
    let first_masked = (winner as u16).wrapping_sub(1);
    s.iter()
        .zip(0u16..)
        .map(|(&v, i)| {
            if i.wrapping_sub(first_masked) > 2 {
                v
            } else {
                u16::MAX
            }
        })
        .min()
        .unwrap_or(u16::MAX)
}

/// The smallest value of `s` and its first index (`(u16::MAX, 0)` for an empty slice).
#[inline(always)]
fn first_min(s: &[u16]) -> (u16, usize) {
    // `value << 16 | index`: the minimum is the smallest value at its first index.
    let packed = s
        .iter()
        .enumerate()
        .map(|(i, &v)| (v as u32) << 16 | i as u32)
        .min()
        .unwrap_or((u16::MAX as u32) << 16);
    ((packed >> 16) as u16, (packed & 0xFFFF) as usize)
}

pub use super::speckle::remove_speckles;

/// Local sub-pixel refinement: for every pixel with an estimate, a few Gauss–Newton steps
/// (Lucas–Kanade in one dimension) on the grey levels of a `(2r+1)²` window move the disparity
/// to where the window matches best, with the window's mean and contrast removed (exposure
/// changes) and neighbours weighted by their grey-level similarity to the centre (so a window
/// straddling an object boundary listens to its own side). The integer-grid costs of census and
/// SAD cannot resolve disparity finer than about 0.2 px; the grey levels can.
///
/// A pixel keeps its value when its window has no horizontal texture or the steps drift more than
/// half a pixel away.
pub fn refine_locally(
    disparity: &mut Raster<f32>,
    left: &Raster<u8>,
    right: &Raster<u8>,
    radius: usize,
    iterations: u32,
) {
    let (w, h) = (left.width(), left.height());
    if w < 2 {
        return;
    }
    // The right view and its horizontal gradient (central differences, borders replicated) as
    // `f32`, each row padded with zeros so that a window of any disparity reads whole vectors.
    let stride = w + 2 * PAD;
    let mut right_f = vec![0f32; stride * h];
    let mut grad = vec![0f32; stride * h];
    right_f
        .par_chunks_mut(stride)
        .zip(grad.par_chunks_mut(stride))
        .enumerate()
        .for_each(|(y, (rf, g))| {
            let row = right.row(y);
            for (x, (rf, g)) in rf[PAD..PAD + w]
                .iter_mut()
                .zip(&mut g[PAD..PAD + w])
                .enumerate()
            {
                *rf = row[x] as f32;
                let a = row[x.saturating_sub(1)] as f32;
                let b = row[(x + 1).min(w - 1)] as f32;
                *g = 0.5 * (b - a);
            }
        });
    let mut similarity = [0f32; 256];
    for (d, s) in similarity.iter_mut().enumerate() {
        *s = (-(d as f32) / 12.0).exp();
    }
    let src = disparity.pixels().to_vec();
    let ctx = LocalFit {
        left,
        right: &right_f,
        grad: &grad,
        stride,
        similarity: &similarity,
        radius: radius.min(MAX_RADIUS),
        iterations,
    };
    disparity
        .pixels_mut()
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, out)| refine_row_fast(&ctx, &src[y * w..(y + 1) * w], y, out));
}

/// Zeros on each side of a padded row of [`LocalFit`]: at least one window width.
const PAD: usize = 16;

/// Largest window radius of the local fit (window 9×9).
const MAX_RADIUS: usize = 4;

crate::avx2_variant!(fn refine_row_fast<'a, 'b>(ctx: &'b LocalFit<'a>, src: &'b [f32], y: usize, out: &'b mut [f32]) => refine_row);

/// [`LocalFit::fit`] on every estimate of row `y` (`src` the row before refinement).
#[inline(always)]
fn refine_row(ctx: &LocalFit<'_>, src: &[f32], y: usize, out: &mut [f32]) {
    // Windows of up to 7 columns fit one 8-lane vector, 9 columns two.
    if ctx.radius <= 3 {
        refine_row_with::<8>(ctx, src, y, out)
    } else {
        refine_row_with::<16>(ctx, src, y, out)
    }
}

#[inline(always)]
fn refine_row_with<const NC: usize>(ctx: &LocalFit<'_>, src: &[f32], y: usize, out: &mut [f32]) {
    for (x, (o, &d0)) in out.iter_mut().zip(src).enumerate() {
        if d0.is_nan() {
            continue;
        }
        if let Some(d) = ctx.fit::<NC>(x, y, d0) {
            *o = d;
        }
    }
}

/// Inputs of the local fit of [`refine_locally`].
struct LocalFit<'a> {
    left: &'a Raster<u8>,
    /// Right view, rows of `stride` values with [`PAD`] zeros on each side.
    right: &'a [f32],
    /// Horizontal gradient of the right view, laid out as `right`.
    grad: &'a [f32],
    stride: usize,
    similarity: &'a [f32; 256],
    radius: usize,
    iterations: u32,
}

impl LocalFit<'_> {
    /// The refined disparity of pixel (x, y) from `d0`, or `None` to keep `d0`.
    ///
    /// One pass over the window per step accumulates weighted sums (values taken relative to the
    /// centre's grey level, so the variances do not cancel in `f32`); means, variances and the
    /// Gauss–Newton step follow from them. Each window row is `NC` lanes wide (columns past the
    /// window weigh 0), so every sum is a whole-vector operation.
    #[inline(always)]
    fn fit<const NC: usize>(&self, x: usize, y: usize, d0: f32) -> Option<f32> {
        let (w, h) = (self.left.width(), self.left.height());
        let r = self.radius;
        let centre = *self.left.get(x, y);
        let cf = centre as f32;
        let (y0, y1) = (y.saturating_sub(r), (y + r).min(h - 1));
        let (x0, x1) = (x.saturating_sub(r), (x + r).min(w - 1));
        let cols = x1 + 1 - x0;
        let rows = y1 + 1 - y0;
        // The window's weights and left values (relative to the centre) do not depend on d:
        // once per pixel, `NC` lanes a row, zero weight past the window.
        let mut wt = [[0f32; NC]; 2 * MAX_RADIUS + 1];
        let mut lv = [[0f32; NC]; 2 * MAX_RADIUS + 1];
        for (j, yy) in (y0..=y1).enumerate() {
            let row = &self.left.row(yy)[x0..=x1];
            for (i, &v) in row.iter().enumerate() {
                wt[j][i] = self.similarity[v.abs_diff(centre) as usize];
                lv[j][i] = v as f32 - cf;
            }
        }
        let top = (w - 1) as f32;
        let mut d = d0;
        for _ in 0..self.iterations {
            // Window columns whose match x − d lies inside the right image.
            let lo = x0.max(d.max(0.0).ceil() as usize);
            let hi_f = (top + d).floor();
            if !hi_f.is_finite() || hi_f < lo as f32 {
                return None;
            }
            let hi = x1.min(hi_f as usize);
            if hi < lo {
                return None;
            }
            let mut inside = [0f32; NC];
            for (i, m) in inside.iter_mut().enumerate().take(cols) {
                if (lo..=hi).contains(&(x0 + i)) {
                    *m = 1.0;
                }
            }
            // Column x0 + i matches xs = x0 + i − d = xi + i + f: one fraction for the window.
            // lo ≤ hi keeps the reads within the padding; the check below is for safety.
            let xs0 = x0 as f32 - d;
            let xi = xs0.floor();
            let f = xs0 - xi;
            let start = PAD as isize + xi as isize;
            if start < 0 || start as usize + NC + 1 > self.stride {
                return None;
            }
            let start = start as usize;
            let mut acc = [[0f32; NC]; 9];
            for (j, yy) in (y0..=y1).enumerate() {
                let at = yy * self.stride + start;
                let lanes = |v: &[f32], from: usize| -> Option<[f32; NC]> {
                    v.get(from..from + NC)?.try_into().ok()
                };
                let (Some(r0), Some(r1), Some(g0), Some(g1)) = (
                    lanes(self.right, at),
                    lanes(self.right, at + 1),
                    lanes(self.grad, at),
                    lanes(self.grad, at + 1),
                ) else {
                    return None;
                };
                let (wj, lj) = (&wt[j], &lv[j]);
                let [a0, a1, a2, a3, a4, a5, a6, a7, a8] = &mut acc;
                for i in 0..NC {
                    let rv = r0[i] + f * (r1[i] - r0[i]) - cf;
                    let g = g0[i] + f * (g1[i] - g0[i]);
                    let (q, l) = (wj[i] * inside[i], lj[i]);
                    a0[i] += q;
                    a1[i] += q * l;
                    a2[i] += q * rv;
                    a3[i] += q * g;
                    a4[i] += q * l * l;
                    a5[i] += q * rv * rv;
                    a6[i] += q * g * g;
                    a7[i] += q * l * g;
                    a8[i] += q * rv * g;
                }
            }
            let [sw, sl, sr, sg, sll, srr, sgg, slg, srg] = acc.map(|a| a.iter().sum::<f32>());
            let n = (hi + 1 - lo) * rows;
            if n < 4 || sw <= 0.0 {
                return None;
            }
            let (ml, mr, mg) = (sl / sw, sr / sw, sg / sw);
            let vl = (sll - sw * ml * ml).max(0.0);
            let vr = (srr - sw * mr * mr).max(0.0);
            let gain = if vl > 1e-3 { (vr / vl).sqrt() } else { 1.0 };
            // Residual of L(p) ≈ R(p − d): moving d by δ changes R by −g·δ.
            let eg = gain * (slg - sw * ml * mg) - (srg - sw * mr * mg);
            let gg = sgg - sw * mg * mg;
            if gg < 4.0 * sw {
                // Under ~2 grey levels per pixel of horizontal gradient: no reliable texture.
                return None;
            }
            let delta = (-eg / gg).clamp(-0.5, 0.5);
            d += delta;
            if delta.abs() < 0.005 {
                break;
            }
        }
        (d.is_finite() && (d - d0).abs() <= 0.5).then_some(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subpixel_recovers_the_vertex_and_guards_degenerate_curves() {
        // c(t) = (t − 0.3)² has its vertex at 0.3.
        let c = |t: f32| (t - 0.3) * (t - 0.3);
        let off = subpixel_offset(Subpixel::Parabola, c(-1.0), c(0.0), c(1.0));
        assert!((off - 0.3).abs() < 1e-5);
        // V-shape with vertex 0.2: c(t) = |t − 0.2|.
        let v = |t: f32| (t - 0.2f32).abs();
        let off = subpixel_offset(Subpixel::Equiangular, v(-1.0), v(0.0), v(1.0));
        assert!((off - 0.2).abs() < 1e-5);
        for m in [Subpixel::Parabola, Subpixel::Equiangular] {
            assert_eq!(subpixel_offset(m, 5.0, 5.0, 5.0), 0.0);
            assert_eq!(subpixel_offset(m, 1e30, 0.0, 1e30), 0.0);
            let o = subpixel_offset(m, 0.0, 0.0, 100.0);
            assert!((-0.5..=0.5).contains(&o));
        }
    }

    /// `decide` written out plainly: every pixel's window searched with its own loops, the
    /// right view's winners found by visiting every (pixel, disparity) pair, and a failed pixel
    /// called occluded when no disparity of the whole range would pass the check.
    fn plain_decide(
        agg: &Aggregated,
        bases: Option<&[u16]>,
        opts: &DecideOptions,
    ) -> (Vec<f32>, Vec<PixelState>, Vec<f32>) {
        let (w, h, k) = (agg.width, agg.height, agg.k);
        let unit = opts.confidence_unit.max(1e-3) * agg.paths as f32;
        let mut disp = vec![f32::NAN; w * h];
        let mut state = vec![PixelState::Valid; w * h];
        let mut conf = vec![0f32; w * h];
        let top = bases.map_or(k, |b| b.iter().map(|&v| v as usize + k).max().unwrap_or(k));
        for y in 0..h {
            let base = |x: usize| bases.map_or(0, |b| b[y * w + x] as usize);
            let cost = |x: usize, i: usize| agg.s[(y * w + x) * k + i];
            // (cost, disparity) of each right pixel's best match, smallest disparity on ties.
            let mut right: Vec<Option<(u16, usize)>> = vec![None; w];
            for x in 0..w {
                for i in 0..k {
                    let d = base(x) + i;
                    if d <= x {
                        let c = (cost(x, i), d);
                        let r = &mut right[x - d];
                        if r.is_none_or(|best| c < best) {
                            *r = Some(c);
                        }
                    }
                }
            }
            for x in 0..w {
                let p = y * w + x;
                let mut bi = 0;
                for i in 1..k {
                    if cost(x, i) < cost(x, bi) {
                        bi = i;
                    }
                }
                let bv = cost(x, bi);
                conf[p] = 1.0 / (1.0 + bv.saturating_sub(agg.min_sum[p]) as f32 / unit);
                let d = base(x) + bi;
                let other = (0..k)
                    .filter(|&i| i.abs_diff(bi) > 1)
                    .map(|i| cost(x, i))
                    .min();
                let unique = opts.uniqueness == 0
                    || other.is_none_or(|v| {
                        (v as u64) * (100 - opts.uniqueness as u64) >= bv as u64 * 100
                    });
                let passes = |x: usize, d: usize, tol: u32| {
                    d <= x && right[x - d].is_some_and(|(_, dr)| dr.abs_diff(d) as u32 <= tol)
                };
                let consistent = opts.lr_max_diff.is_none_or(|tol| passes(x, d, tol));
                if !(unique && consistent) {
                    // Any failed pixel (not unique, or inconsistent) is occluded when no
                    // disparity at all would pass the check.
                    let hidden = opts
                        .lr_max_diff
                        .is_some_and(|tol| !(0..top).any(|d| passes(x, d, tol)));
                    state[p] = if hidden {
                        PixelState::Occluded
                    } else {
                        PixelState::Mismatch
                    };
                    continue;
                }
                let off = if bi > 0 && bi + 1 < k {
                    let c = |i: usize| cost(x, i) as f32;
                    subpixel_offset(opts.subpixel, c(bi - 1), c(bi), c(bi + 1))
                } else {
                    0.0
                };
                disp[p] = d as f32 + off;
            }
        }
        (disp, state, conf)
    }

    #[test]
    fn decide_matches_the_plain_search_with_ties_windows_and_borders() {
        use crate::mesh::surfaces::XorShift;
        let mut rng = XorShift(0x5eed_cafe);
        let mut cases = 0;
        for (w, h, k, max_d) in [
            (1, 1, 1, 0),
            (5, 2, 3, 2),
            (7, 3, 4, 10),
            (37, 4, 16, 15),
            (40, 3, 21, 30),
            (64, 2, 32, 60),
            (23, 2, 40, 39),
        ] {
            for windowed in [false, true] {
                if windowed && max_d + 1 == k {
                    continue;
                }
                for (uniqueness, lr, subpixel) in [
                    (0, None, Subpixel::Parabola),
                    (5, Some(1), Subpixel::Equiangular),
                    (15, Some(0), Subpixel::Parabola),
                    (0, Some(2), Subpixel::Equiangular),
                ] {
                    // Few cost levels, so that ties are common.
                    let s: Vec<u16> = (0..w * h * k)
                        .map(|_| (rng.next_u64() % 12) as u16)
                        .collect();
                    let min_sum: Vec<u16> =
                        (0..w * h).map(|_| (rng.next_u64() % 6) as u16).collect();
                    let bases: Vec<u16> = (0..w * h)
                        .map(|_| (rng.next_u64() % (max_d + 2 - k) as u64) as u16)
                        .collect();
                    let agg = Aggregated {
                        width: w,
                        height: h,
                        k,
                        s,
                        min_sum,
                        paths: 4,
                    };
                    let bases = windowed.then_some(bases.as_slice());
                    let opts = DecideOptions {
                        subpixel,
                        uniqueness,
                        lr_max_diff: lr,
                        confidence_unit: 3.0,
                    };
                    let got = decide(&agg, bases, &opts);
                    let (disp, state, conf) = plain_decide(&agg, bases, &opts);
                    let what = format!("{w}×{h}, k {k}, windowed {windowed}, {opts:?}");
                    assert_eq!(got.state, state, "states, {what}");
                    for (a, b) in got.disparity.pixels().iter().zip(&disp) {
                        assert!(
                            a.to_bits() == b.to_bits() || a.is_nan() && b.is_nan(),
                            "{a} vs {b}, {what}"
                        );
                    }
                    assert_eq!(
                        got.confidence.pixels(),
                        conf.as_slice(),
                        "confidence, {what}"
                    );
                    cases += 1;
                }
            }
        }
        assert_eq!(cases, 40);
    }
}
