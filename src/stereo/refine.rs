//! From aggregated costs to a disparity map: winner-takes-all, the uncertainty term `U_p`
//! (eq. 3.5) as a confidence, sub-pixel refinement, uniqueness and the left/right consistency
//! check; speckle removal ([`remove_speckles`]) lives in [`super::speckle`].

use rayon::prelude::*;

use super::cost::{inside_right_view, CostRows};
use super::options::Subpixel;
use super::sgm::Aggregated;
use super::simd::GreyExponentials;
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

/// Sets to 0 the `confidence` of every pixel whose matching costs (`costs`, window
/// `bases[p]..bases[p]+k` as aggregated) are the same at each disparity inside the right view, and
/// of every pixel with a single disparity inside it (the first columns, whose one candidate wins
/// unopposed); returns how many. Such a pixel carries no evidence: on a textureless stretch wider
/// than the search (or one clipped to black or white) every disparity matches equally well, and
/// its winner is whatever aggregation carried in. On a wholly flat pair that was disparity 0 from
/// the image's left border, where larger disparities fall outside the right view, with `U_p` 0,
/// so every pixel came out at infinity with full confidence. The disparity is kept: aggregation's
/// guess across a textureless stretch is what the smoothness term is for, and on the built-in
/// renders treating such pixels as holes to fill made the reconstruction worse
/// (docs/stereo-eval.md, stop 49).
pub fn mark_textureless(
    costs: &dyn CostRows,
    bases: Option<&[u16]>,
    k: usize,
    confidence: &mut Raster<f32>,
) -> usize {
    let w = costs.width();
    confidence
        .pixels_mut()
        .par_chunks_mut(w)
        .enumerate()
        .map_init(
            || vec![0u8; w * k],
            |row, (y, conf)| {
                let bases = bases.map(|b| &b[y * w..(y + 1) * w]);
                costs.row(y, bases, k, row);
                let mut marked = 0;
                for (x, c) in row.chunks_exact(k).enumerate() {
                    let base = bases.map_or(0, |b| b[x] as usize);
                    let inside = inside_right_view(x, base, k);
                    if inside >= 1 && c[1..inside].iter().all(|&v| v == c[0]) {
                        conf[x] = 0.0;
                        marked += 1;
                    }
                }
                marked
            },
        )
        .sum()
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

/// [`decide_row`] for this CPU. With AVX2 (which includes SSE4.1), each pixel's minima come from
/// `phminposuw` (the smallest of eight `u16` and its first index in one instruction), and the
/// usual coarse-to-fine windows get a copy of the loop with their length known at compile time.
/// Elsewhere, the plain loops.
fn decide_row_fast(
    input: &RowInput<'_>,
    disp: &mut [f32],
    st: &mut [PixelState],
    conf: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    if super::simd::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe {
            match input.agg.k {
                16 => decide_row_avx2::<16>(input, disp, st, conf),
                32 => decide_row_avx2::<32>(input, disp, st, conf),
                _ => decide_row_avx2::<0>(input, disp, st, conf),
            }
        }
        return;
    }
    decide_row::<0, false>(input, disp, st, conf)
}

/// [`decide_row`] compiled for AVX2, with `phminposuw`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn decide_row_avx2<const K: usize>(
    input: &RowInput<'_>,
    disp: &mut [f32],
    st: &mut [PixelState],
    conf: &mut [f32],
) {
    decide_row::<K, true>(input, disp, st, conf)
}

/// Winner, sub-pixel, uniqueness and L/R check of one row. `K` is the window's length
/// (`agg.k`) when known at compile time, 0 otherwise; `MINPOS`: use [`minpos`], only where the
/// code runs on a CPU with SSE4.1.
#[inline(always)]
fn decide_row<const K: usize, const MINPOS: bool>(
    input: &RowInput<'_>,
    disp: &mut [f32],
    st: &mut [PixelState],
    conf: &mut [f32],
) {
    let RowInput {
        agg,
        bases,
        opts,
        unit,
        y,
    } = *input;
    debug_assert!(K == 0 || K == agg.k);
    let (w, k) = (agg.width, if K > 0 { K } else { agg.k });
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
        let (bv, bi) = winner::<MINPOS>(s);
        // Right view: disparities d = base + i ≤ x only, i.e. right pixels x − base − i.
        if x >= base {
            let valid = inside_right_view(x, base, k);
            let m0 = w - 1 - (x - base);
            if valid == k {
                // The usual case, a whole window (of constant length when K is known).
                update_right(&mut mirrored[m0..m0 + k], &s[..k], base as u32);
            } else {
                update_right(&mut mirrored[m0..m0 + valid], &s[..valid], base as u32);
            }
        }
        best_left[x] = (base + bi) as u32;
        // U_p here, its confidence after the loop (divisions vectorise there, not here).
        conf[x] = bv.saturating_sub(agg.min_sum[y * w + x]) as f32;
        // Unique when every disparity not adjacent to the winner costs at least
        // bv / (1 − uniqueness), and more than bv: compare the smallest of them once.
        if opts.uniqueness > 0 && (bi >= 2 || bi + 2 < k) {
            let other = runner_up::<MINPOS>(s, bi);
            if !unique(bv, other, opts.uniqueness) {
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
    // Indexed over slices of one length: the compiler vectorises this form (with a zipped
    // `0u32..` counter it kept the loop scalar).
    let n = mirrored.len().min(costs.len());
    let (mirrored, costs) = (&mut mirrored[..n], &costs[..n]);
    for i in 0..n {
        mirrored[i] = mirrored[i].min((costs[i] as u32) << 16 | (base + i as u32));
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

/// [`first_min`], by [`minpos`] when `MINPOS`.
#[inline(always)]
fn winner<const MINPOS: bool>(s: &[u16]) -> (u16, usize) {
    #[cfg(target_arch = "x86_64")]
    if MINPOS {
        // SAFETY: `MINPOS` is only set in code that runs on CPUs with AVX2 (`decide_row_fast`).
        return unsafe { minpos::first_min(s) };
    }
    first_min(s)
}

/// [`min_away_from`], by [`minpos`] when `MINPOS`.
#[inline(always)]
/// Whether a winner of cost `best` is unique against the cheapest disparity not adjacent to it
/// (cost `other`) at a margin of `uniqueness` percent: `other` must cost at least
/// `best / (1 − uniqueness)`, and more than `best`. The second condition only matters at a cost
/// of 0: on a textureless stretch every disparity matches perfectly, and a tie at 0 passed the
/// margin alone, so a flat pair came out as disparity 0 everywhere (everything at infinity) with
/// full confidence.
fn unique(best: u16, other: u16, uniqueness: u32) -> bool {
    other > best && (other as u64) * (100 - uniqueness as u64) >= best as u64 * 100
}

fn runner_up<const MINPOS: bool>(s: &[u16], winner: usize) -> u16 {
    #[cfg(target_arch = "x86_64")]
    if MINPOS {
        // SAFETY: as in `winner`.
        return unsafe { minpos::min_away_from(s, winner) };
    }
    min_away_from(s, winner)
}

/// [`first_min`] and [`min_away_from`] eight disparities at a time with SSE4.1's `phminposuw`.
/// The compiler cannot find that instruction itself: its plain loops keep a running minimum and
/// its index in scalar registers, which took most of the decision's time.
#[cfg(target_arch = "x86_64")]
mod minpos {
    use std::arch::x86_64::*;

    /// As [`super::first_min`].
    ///
    /// # Safety
    /// The CPU must support SSE4.1.
    #[inline]
    #[target_feature(enable = "sse4.1")]
    pub unsafe fn first_min(s: &[u16]) -> (u16, usize) {
        let mut best = (u16::MAX as u32) << 16;
        let chunks = s.chunks_exact(8);
        let tail = chunks.remainder();
        for (c, chunk) in chunks.enumerate() {
            // SAFETY: `chunk` holds eight u16 (16 bytes); unaligned loads are allowed.
            let v = unsafe { _mm_loadu_si128(chunk.as_ptr().cast()) };
            // Bits 0–15: the smallest value; bits 16–18: its first index in the chunk.
            let m = _mm_cvtsi128_si32(_mm_minpos_epu16(v)) as u32;
            best = best.min((m & 0xFFFF) << 16 | (8 * c as u32 + (m >> 16)));
        }
        let start = s.len() - tail.len();
        for (i, &v) in tail.iter().enumerate() {
            best = best.min((v as u32) << 16 | (start + i) as u32);
        }
        ((best >> 16) as u16, (best & 0xFFFF) as usize)
    }

    /// As [`super::min_away_from`].
    ///
    /// # Safety
    /// The CPU must support SSE4.1.
    #[inline]
    #[target_feature(enable = "sse4.1")]
    pub unsafe fn min_away_from(s: &[u16], winner: usize) -> u16 {
        // As in the plain version: index i is masked when i − (winner − 1) is 0, 1 or 2
        // (wrapping), here per lane: min(rel, 2) == rel.
        let first_masked = (winner as u16).wrapping_sub(1);
        let lanes = _mm_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7);
        let two = _mm_set1_epi16(2);
        let mut acc = _mm_set1_epi16(-1);
        let chunks = s.chunks_exact(8);
        let tail = chunks.remainder();
        for (c, chunk) in chunks.enumerate() {
            // SAFETY: as in `first_min`.
            let v = unsafe { _mm_loadu_si128(chunk.as_ptr().cast()) };
            let offset = (8 * c as u16).wrapping_sub(first_masked);
            let rel = _mm_add_epi16(lanes, _mm_set1_epi16(offset as i16));
            let masked = _mm_cmpeq_epi16(_mm_min_epu16(rel, two), rel);
            acc = _mm_min_epu16(acc, _mm_or_si128(v, masked));
        }
        let mut best = _mm_cvtsi128_si32(_mm_minpos_epu16(acc)) as u16;
        let start = s.len() - tail.len();
        for (i, &v) in tail.iter().enumerate() {
            if ((start + i) as u16).wrapping_sub(first_masked) > 2 {
                best = best.min(v);
            }
        }
        best
    }
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
    // Both views, `e^(±I/s)` of the left view (s = SIMILARITY_SCALE), from which a window's
    // similarity weights `e^(−|I − I_centre|/s)` are products, and the right view's horizontal
    // gradient (central differences, borders replicated) as `f32`, each row padded with zeros
    // so that a window of any disparity reads whole vectors.
    let stride = w + 2 * PAD;
    let GreyExponentials {
        rise: rise_of,
        fall: fall_of,
    } = GreyExponentials::new(SIMILARITY_SCALE);
    let mut left_f = vec![0f32; stride * h];
    let mut rise = vec![0f32; stride * h];
    let mut fall = vec![0f32; stride * h];
    let mut right_f = vec![0f32; stride * h];
    let mut grad = vec![0f32; stride * h];
    left_f
        .par_chunks_mut(stride)
        .zip(rise.par_chunks_mut(stride))
        .zip(fall.par_chunks_mut(stride))
        .zip(right_f.par_chunks_mut(stride))
        .zip(grad.par_chunks_mut(stride))
        .enumerate()
        .for_each(|(y, ((((lf, up), down), rf), g))| {
            for (((lf, up), down), &v) in lf[PAD..PAD + w]
                .iter_mut()
                .zip(&mut up[PAD..PAD + w])
                .zip(&mut down[PAD..PAD + w])
                .zip(left.row(y))
            {
                *lf = v as f32;
                *up = rise_of[v as usize];
                *down = fall_of[v as usize];
            }
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
    let src = disparity.pixels().to_vec();
    let ctx = LocalFit {
        width: w,
        height: h,
        left: &left_f,
        rise: &rise,
        fall: &fall,
        right: &right_f,
        grad: &grad,
        stride,
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

/// Grey-level difference over which a neighbour's weight in the local fit falls by `e`.
const SIMILARITY_SCALE: f32 = 12.0;

crate::avx2_variant!(fn refine_row_fast<'a, 'b>(ctx: &'b LocalFit<'a>, src: &'b [f32], y: usize, out: &'b mut [f32]) => refine_row);

/// [`LocalFit::fit_batch`] on every estimate of row `y` (`src` the row before refinement).
#[inline(always)]
fn refine_row(ctx: &LocalFit<'_>, src: &[f32], y: usize, out: &mut [f32]) {
    // Windows of up to 7 columns fit one 8-lane vector, 9 columns two.
    if ctx.radius <= 3 {
        refine_row_with::<8>(ctx, src, y, out)
    } else {
        refine_row_with::<16>(ctx, src, y, out)
    }
}

/// Pixels fitted together. Their window sums do not depend on each other, so the processor
/// overlaps them, and the arithmetic of a step after the sums runs on all of them at once: a
/// pixel alone is one long chain of dependent divisions, a square root and the next step's
/// addresses.
const BATCH: usize = 8;

#[inline(always)]
fn refine_row_with<const NC: usize>(ctx: &LocalFit<'_>, src: &[f32], y: usize, out: &mut [f32]) {
    // The batch's windows, rewritten in place (a fresh one is 1–2 KB to zero and move).
    let mut windows: [Window<NC>; BATCH] = std::array::from_fn(|_| Window::default());
    let mut batch = [0usize; BATCH];
    let mut n = 0;
    for (x, d0) in src.iter().enumerate() {
        if d0.is_nan() {
            continue;
        }
        batch[n] = x;
        n += 1;
        if n == BATCH {
            ctx.fit_batch(&mut windows, &batch, y, src, out);
            n = 0;
        }
    }
    ctx.fit_batch(&mut windows, &batch[..n], y, src, out);
}

/// The sum of a vector's lanes, halves added to halves until one lane is left: a few shuffles,
/// where adding the lanes in order is a chain of dependent additions.
#[inline(always)]
fn lane_sum<const NC: usize>(a: &[f32; NC]) -> f32 {
    let mut v = *a;
    let mut n = NC;
    while n > 1 {
        // An odd count keeps its middle lane for the next round.
        let (half, odd) = (n / 2, n % 2);
        for i in 0..half {
            v[i] += v[i + half + odd];
        }
        n = half + odd;
    }
    v[0]
}

/// `NC` values of a padded image from index `at` (`None` past its end).
#[inline(always)]
fn lanes<const NC: usize>(image: &[f32], at: usize) -> Option<[f32; NC]> {
    image.get(at..at + NC)?.try_into().ok()
}

/// Inputs of the local fit of [`refine_locally`]. The five images are rows of `stride` values
/// with [`PAD`] zeros on each side.
struct LocalFit<'a> {
    width: usize,
    height: usize,
    /// Left view.
    left: &'a [f32],
    /// `e^(I/s)` of the left view, s = [`SIMILARITY_SCALE`].
    rise: &'a [f32],
    /// `e^(−I/s)` of the left view.
    fall: &'a [f32],
    /// Right view.
    right: &'a [f32],
    /// Horizontal gradient of the right view.
    grad: &'a [f32],
    stride: usize,
    radius: usize,
    iterations: u32,
}

/// A pixel's window in the left view, `NC` lanes a row (lane `i` is column `x0 + i`): the
/// weights, which fall with the grey-level difference from the centre and are 0 past the window,
/// and the grey levels relative to the centre's. Neither depends on the disparity. Rows past
/// `rows` are left over from other pixels.
struct Window<const NC: usize> {
    x0: usize,
    x1: usize,
    y0: usize,
    rows: usize,
    centre: f32,
    weight: [[f32; NC]; 2 * MAX_RADIUS + 1],
    value: [[f32; NC]; 2 * MAX_RADIUS + 1],
    /// `weight × value`.
    weighted: [[f32; NC]; 2 * MAX_RADIUS + 1],
    /// Σ weight, Σ weight·value, Σ weight·value² over the whole window.
    sums: [f32; 3],
}

impl<const NC: usize> Default for Window<NC> {
    fn default() -> Self {
        Window {
            x0: 0,
            x1: 0,
            y0: 0,
            rows: 0,
            centre: 0.0,
            weight: [[0f32; NC]; 2 * MAX_RADIUS + 1],
            value: [[0f32; NC]; 2 * MAX_RADIUS + 1],
            weighted: [[0f32; NC]; 2 * MAX_RADIUS + 1],
            sums: [0.0; 3],
        }
    }
}

/// Sums over a window at one disparity ([`LocalFit::step_sums`]), each weighted: of the weights,
/// the left values, the right values, the gradients, and of the products left², right²,
/// gradient², left·gradient, right·gradient. Grey levels are taken relative to the centre's, so
/// that the variances do not cancel in `f32`.
type Sums = [f32; 9];

impl LocalFit<'_> {
    /// Refines the disparities of row `y`'s pixels `xs` (at most [`BATCH`]) from `src` into
    /// `out`; a pixel whose window has no horizontal texture, or whose steps drift more than
    /// half a pixel away, keeps its value.
    ///
    /// Gauss–Newton steps, each from weighted sums over the window ([`Self::step_sums`]): the
    /// window's means and variances follow from them, and the step from the residual's
    /// correlation with the gradient.
    #[inline(always)]
    fn fit_batch<const NC: usize>(
        &self,
        windows: &mut [Window<NC>; BATCH],
        xs: &[usize],
        y: usize,
        src: &[f32],
        out: &mut [f32],
    ) {
        let mut d0 = [0f32; BATCH];
        // Whether each pixel is still stepping, and whether it has given up.
        let mut stepping = [false; BATCH];
        let mut failed = [true; BATCH];
        for (b, (&x, win)) in xs.iter().zip(windows.iter_mut()).enumerate() {
            d0[b] = src[x];
            if self.window(win, x, y).is_some() {
                (stepping[b], failed[b]) = (true, false);
            }
        }
        let mut d = d0;
        for _ in 0..self.iterations {
            // Each sum as one array over the batch (pixels not stepping keep zeros).
            let mut sums = [[0f32; BATCH]; 9];
            for (b, win) in windows.iter().enumerate().take(xs.len()) {
                if !stepping[b] {
                    continue;
                }
                match self.step_sums(win, d[b]) {
                    Some(v) => {
                        for (s, v) in sums.iter_mut().zip(v) {
                            s[b] = v;
                        }
                    }
                    None => (stepping[b], failed[b]) = (false, true),
                }
            }
            let [sw, sl, sr, sg, sll, srr, sgg, slg, srg] = &sums;
            let mut delta = [0f32; BATCH];
            let mut textured = [false; BATCH];
            for b in 0..BATCH {
                let (ml, mr, mg) = (sl[b] / sw[b], sr[b] / sw[b], sg[b] / sw[b]);
                let vl = (sll[b] - sw[b] * ml * ml).max(0.0);
                let vr = (srr[b] - sw[b] * mr * mr).max(0.0);
                let gain = if vl > 1e-3 { (vr / vl).sqrt() } else { 1.0 };
                // Residual of L(p) ≈ R(p − d): moving d by δ changes R by −g·δ.
                let eg = gain * (slg[b] - sw[b] * ml * mg) - (srg[b] - sw[b] * mr * mg);
                let gg = sgg[b] - sw[b] * mg * mg;
                // Under ~2 grey levels per pixel of horizontal gradient: no reliable texture.
                textured[b] = gg >= 4.0 * sw[b];
                delta[b] = (-eg / gg).clamp(-0.5, 0.5);
            }
            for b in 0..xs.len() {
                if !stepping[b] {
                    continue;
                }
                if !textured[b] {
                    (stepping[b], failed[b]) = (false, true);
                    continue;
                }
                d[b] += delta[b];
                if delta[b].abs() < 0.005 {
                    stepping[b] = false;
                }
            }
            if !stepping.iter().any(|&s| s) {
                break;
            }
        }
        for (b, &x) in xs.iter().enumerate() {
            if !failed[b] && d[b].is_finite() && (d[b] - d0[b]).abs() <= 0.5 {
                out[x] = d[b];
            }
        }
    }

    /// The window's [`Sums`] at disparity `d`, or `None` when too little of it matches inside
    /// the right image.
    #[inline(always)]
    fn step_sums<const NC: usize>(&self, win: &Window<NC>, d: f32) -> Option<Sums> {
        let (x0, x1) = (win.x0, win.x1);
        let top = (self.width - 1) as f32;
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
        // Usually the whole window matches inside the right image, and the sums of the left
        // view alone are the window's own; near the left border some columns drop out.
        let sums = if lo == x0 && hi == x1 {
            self.sums::<NC, false>(win, start, f, &[1.0; NC])?
        } else {
            let mut inside = [0f32; NC];
            for (i, m) in inside.iter_mut().enumerate() {
                *m = ((lo..=hi).contains(&(x0 + i))) as u32 as f32;
            }
            self.sums::<NC, true>(win, start, f, &inside)?
        };
        let n = (hi + 1 - lo) * win.rows;
        (n >= 4 && sums[0] > 0.0).then_some(sums)
    }

    /// Makes `win` the left window of pixel (x, y) ([`Window`]); `None` if a row cannot be read
    /// (never within the image, since rows are padded by more than a window).
    #[inline(always)]
    fn window<const NC: usize>(&self, win: &mut Window<NC>, x: usize, y: usize) -> Option<()> {
        let (w, h, r) = (self.width, self.height, self.radius);
        let at_centre = y * self.stride + PAD + x;
        let centre = *self.left.get(at_centre)?;
        let (rise_c, fall_c) = (*self.rise.get(at_centre)?, *self.fall.get(at_centre)?);
        let (y0, y1) = (y.saturating_sub(r), (y + r).min(h - 1));
        let (x0, x1) = (x.saturating_sub(r), (x + r).min(w - 1));
        let cols = x1 + 1 - x0;
        let mut in_window = [0f32; NC];
        for (i, m) in in_window.iter_mut().enumerate() {
            *m = (i < cols) as u32 as f32;
        }
        (win.x0, win.x1, win.y0, win.rows, win.centre) = (x0, x1, y0, y1 + 1 - y0, centre);
        let mut acc = [[0f32; NC]; 3];
        for j in 0..win.rows {
            let at = (y0 + j) * self.stride + PAD + x0;
            let (row, rise, fall) = (
                lanes::<NC>(self.left, at)?,
                lanes::<NC>(self.rise, at)?,
                lanes::<NC>(self.fall, at)?,
            );
            let [sw, sl, sll] = &mut acc;
            for i in 0..NC {
                let v = row[i] - centre;
                // e^(−|v|/s) as the smaller of e^(±v/s).
                let q = in_window[i] * (rise[i] * fall_c).min(fall[i] * rise_c);
                win.weight[j][i] = q;
                win.value[j][i] = v;
                win.weighted[j][i] = q * v;
                sw[i] += q;
                sl[i] += q * v;
                sll[i] += q * v * v;
            }
        }
        win.sums = std::array::from_fn(|k| lane_sum(&acc[k]));
        Some(())
    }

    /// The window's [`Sums`] with the right view read from padded index `start` on (window row
    /// `j` at `start + (y0 + j)·stride`), interpolated by the fraction `f`. With `MASKED`, column
    /// `i` counts `inside[i]` times (0 or 1) and the left view's sums are taken again; without
    /// it, every column counts and they are the window's own.
    #[inline(always)]
    fn sums<const NC: usize, const MASKED: bool>(
        &self,
        win: &Window<NC>,
        start: usize,
        f: f32,
        inside: &[f32; NC],
    ) -> Option<Sums> {
        let cf = win.centre;
        // Right values, gradients, right², gradient², left·gradient, right·gradient; then, with
        // MASKED, weights, left values, left².
        let mut acc = [[0f32; NC]; 9];
        for j in 0..win.rows {
            let at = (win.y0 + j) * self.stride + start;
            let (r0, r1, g0, g1) = (
                lanes::<NC>(self.right, at)?,
                lanes::<NC>(self.right, at + 1)?,
                lanes::<NC>(self.grad, at)?,
                lanes::<NC>(self.grad, at + 1)?,
            );
            let (wj, lj, wlj) = (&win.weight[j], &win.value[j], &win.weighted[j]);
            let [sr, sg, srr, sgg, slg, srg, sw, sl, sll] = &mut acc;
            for i in 0..NC {
                let rv = r0[i] + f * (r1[i] - r0[i]) - cf;
                let g = g0[i] + f * (g1[i] - g0[i]);
                let (q, ql) = if MASKED {
                    (wj[i] * inside[i], wlj[i] * inside[i])
                } else {
                    (wj[i], wlj[i])
                };
                let (qr, qg) = (q * rv, q * g);
                sr[i] += qr;
                sg[i] += qg;
                srr[i] += qr * rv;
                sgg[i] += qg * g;
                slg[i] += ql * g;
                srg[i] += qr * g;
                if MASKED {
                    sw[i] += q;
                    sl[i] += ql;
                    sll[i] += ql * lj[i];
                }
            }
        }
        let [sr, sg, srr, sgg, slg, srg, sw, sl, sll]: [f32; 9] =
            std::array::from_fn(|k| lane_sum(&acc[k]));
        let [sw, sl, sll] = if MASKED { [sw, sl, sll] } else { win.sums };
        Some([sw, sl, sr, sg, sll, srr, sgg, slg, srg])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tie_is_never_unique_even_at_cost_zero() {
        // Within the margin: 104 · 0.95 < 100; beyond it: 106 · 0.95 ≥ 100.
        assert!(!unique(100, 104, 5));
        assert!(unique(100, 106, 5));
        // A tie at 0 (two disparities that both match perfectly: a repeated pattern, a flat
        // stretch) passed the margin alone.
        assert!(!unique(0, 0, 5));
        assert!(unique(0, 1, 5));
        assert!(!unique(7, 7, 1));
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn minpos_minima_match_the_plain_ones_with_ties_and_every_winner() {
        if !std::is_x86_feature_detected!("sse4.1") {
            return;
        }
        use crate::mesh::surfaces::XorShift;
        let mut rng = XorShift(0x31a7);
        for len in 0..=41 {
            for round in 0..40 {
                // Few distinct values, so ties are common; some all-saturated windows.
                let top = [3, 50, 65535][round % 3];
                let s: Vec<u16> = (0..len)
                    .map(|_| {
                        if round % 7 == 6 {
                            u16::MAX
                        } else {
                            (rng.below(top) as u16).saturating_mul(if top == 3 { 1 } else { 1300 })
                        }
                    })
                    .collect();
                // SAFETY: SSE4.1 checked above.
                let fast = unsafe { minpos::first_min(&s) };
                assert_eq!(fast, first_min(&s), "first_min of {s:?}");
                for winner in 0..len.max(1) + 1 {
                    // SAFETY: as above.
                    let fast = unsafe { minpos::min_away_from(&s, winner) };
                    assert_eq!(fast, min_away_from(&s, winner), "winner {winner} of {s:?}");
                }
            }
        }
    }

    /// The local fit of one pixel written out plainly: every window pixel visited one at a time,
    /// the similarity weight by `exp`, the right view and its gradient interpolated at `x − d`.
    fn plain_fit(
        left: &Raster<u8>,
        right: &Raster<u8>,
        x: usize,
        y: usize,
        d0: f32,
        r: usize,
        iterations: u32,
    ) -> Option<f32> {
        let (w, h) = (left.width(), left.height());
        let c = *left.get(x, y) as f32;
        let rv = |xx: isize, yy: usize| -> f32 {
            if (0..w as isize).contains(&xx) {
                *right.get(xx as usize, yy) as f32
            } else {
                0.0
            }
        };
        let gv = |xx: isize, yy: usize| -> f32 {
            if !(0..w as isize).contains(&xx) {
                return 0.0;
            }
            let a = rv((xx - 1).max(0), yy);
            let b = rv((xx + 1).min(w as isize - 1), yy);
            0.5 * (b - a)
        };
        let mut d = d0;
        for _ in 0..iterations {
            let mut s = [0f32; 9];
            let mut n = 0;
            for yy in y.saturating_sub(r)..=(y + r).min(h - 1) {
                for xx in x.saturating_sub(r)..=(x + r).min(w - 1) {
                    let xs = xx as f32 - d;
                    if xs < 0.0 || xs > (w - 1) as f32 {
                        continue;
                    }
                    n += 1;
                    let (xi, f) = (xs.floor() as isize, xs - xs.floor());
                    let rr = rv(xi, yy) + f * (rv(xi + 1, yy) - rv(xi, yy)) - c;
                    let g = gv(xi, yy) + f * (gv(xi + 1, yy) - gv(xi, yy));
                    let l = *left.get(xx, yy) as f32 - c;
                    let q = (-l.abs() / SIMILARITY_SCALE).exp();
                    let terms = [1.0, l, rr, g, l * l, rr * rr, g * g, l * g, rr * g];
                    for (s, t) in s.iter_mut().zip(terms) {
                        *s += q * t;
                    }
                }
            }
            let [sw, sl, sr, sg, sll, srr, sgg, slg, srg] = s;
            if n < 4 || sw <= 0.0 {
                return None;
            }
            let (ml, mr, mg) = (sl / sw, sr / sw, sg / sw);
            let vl = (sll - sw * ml * ml).max(0.0);
            let vr = (srr - sw * mr * mr).max(0.0);
            let gain = if vl > 1e-3 { (vr / vl).sqrt() } else { 1.0 };
            let eg = gain * (slg - sw * ml * mg) - (srg - sw * mr * mg);
            let gg = sgg - sw * mg * mg;
            if gg < 4.0 * sw {
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

    #[test]
    fn local_fit_matches_the_plain_fit_of_each_pixel() {
        use crate::mesh::surfaces::XorShift;
        let mut rng = XorShift(0x10ca1);
        let (w, h) = (45, 13);
        // Texture with flat patches (no texture: the fit gives up there), a right view shifted by
        // a disparity varying over the image, and estimates a fraction of a pixel off, some
        // missing, some reaching past the left border.
        let left = Raster::from_fn(w, h, |x, y| {
            if (x / 9 + y / 5) % 4 == 3 {
                90
            } else {
                ((x * 37 + y * 91 + (x * y) % 7 * 23) % 200 + 20) as u8
            }
        });
        let truth = |x: usize, y: usize| 3.0 + 0.1 * x as f32 + 0.2 * y as f32;
        let right = Raster::from_fn(w, h, |x, y| {
            let xs = (x as f32 + truth(x, y)).round() as usize;
            *left.get(xs.min(w - 1), y)
        });
        for (radius, iterations) in [(1, 2), (2, 2), (3, 1), (4, 3)] {
            let estimate = Raster::from_fn(w, h, |x, y| {
                let r = rng.next_u64();
                if r.is_multiple_of(10) {
                    f32::NAN
                } else {
                    truth(x, y) + ((r >> 8) % 1000) as f32 / 1000.0 - 0.5
                }
            });
            let mut refined = estimate.clone();
            refine_locally(&mut refined, &left, &right, radius, iterations);
            let (mut differ, mut moved) = (0, 0);
            for y in 0..h {
                for x in 0..w {
                    let d0 = *estimate.get(x, y);
                    let got = *refined.get(x, y);
                    if d0.is_nan() {
                        assert!(got.is_nan(), "({x}, {y}): a missing estimate stays missing");
                        continue;
                    }
                    let want = plain_fit(&left, &right, x, y, d0, radius, iterations).unwrap_or(d0);
                    moved += (want != d0) as usize;
                    // Sums added in another order can tip a pixel over a threshold.
                    if (got - want).abs() > 2e-3 {
                        differ += 1;
                    }
                }
            }
            assert!(
                differ * 200 <= w * h,
                "radius {radius}: {differ} of {} pixels differ from the plain fit",
                w * h
            );
            // Many pixels are refined: the comparison is not between unchanged inputs.
            assert!(moved * 3 > w * h, "radius {radius}: only {moved} refined");
        }
    }

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
                        v > bv && (v as u64) * (100 - opts.uniqueness as u64) >= bv as u64 * 100
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
            (30, 2, 17, 20),
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
        assert_eq!(cases, 48);
    }
}
