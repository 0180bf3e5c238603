//! Semi-global matching (Hirschmüller 2008; the thesis' eq. 3.3–3.4):
//! `L_r(p,d) = C(p,d) + min(L_r(p−r,d), L_r(p−r,d±1) + P1, min_i L_r(p−r,i) + P2) − min_i L_r(p−r,i)`
//! summed over 4 or 8 path directions into `S(p,d)`, kept as `u16`.
//!
//! The paths run in two sweeps: a forward sweep (top to bottom, left to right: paths from the left,
//! upper-left, top and upper-right) and a backward sweep (the mirror image). The two sweeps run on
//! two threads at once and only meet once, in the middle of the image; each row has a lock. The
//! sweep that reaches a row first writes its `S` and computes its cost row, into a stored volume
//! when the memory bound leaves room for one (a narrow coarse-to-fine window, a coarse level) so
//! that the other sweep reads it there; the second sweep adds its paths. Memory: `S`, the cost
//! volume when stored (1 byte per pixel and disparity), and per sweep two rows of path costs.
//!
//! Each pixel may search its own window of `k` disparities `base(p)..base(p)+k` (coarse-to-fine);
//! a path step reads the neighbour's costs at the pixel's disparities: in place, since each
//! pixel's path costs are stored between runs of `FAR`, when the windows start fewer than 16
//! disparities apart; copied into the pixel's indices when they are further apart.
//!
//! Within a row, each pixel takes all of its paths at once: the path along the row continues from
//! the pixel before it, the vertical and diagonal paths read only the row before, and the pixel's
//! costs and sums are read and written once. The usual coarse-to-fine windows (16 and 32
//! disparities) are compiled at their length.

use std::sync::Mutex;

use super::buffer::{self, Workspace};
use super::cost::CostRows;
use crate::image::Raster;

/// Disparities handled together in the recurrence (16 × u16 = one AVX2 register).
const LANES: usize = 16;

/// Path costs beyond a window's ends: large, and saturating arithmetic keeps them there.
const FAR: u16 = u16::MAX;

/// Aggregated costs `S(p, base(p) + i)` and, per pixel, `Σ_r min_d L_r(p, d)` (for eq. 3.5).
pub struct Aggregated {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Disparities per pixel.
    pub k: usize,
    /// `S`, pixel-major: `s[(y·width + x)·k + i]`.
    pub s: Vec<u16>,
    /// `Σ_r min_d L_r(p, d)` per pixel (saturating).
    pub min_sum: Vec<u16>,
    /// Number of paths summed.
    pub paths: u32,
}

impl Aggregated {
    /// Gives `S` and `min_sum` back to `spare`.
    pub fn recycle(self, spare: &mut Workspace) {
        spare.give_back_aggregated(self.s, self.min_sum);
    }
}

/// SGM penalties after clamping, and the P2 reduction table indexed by `|ΔI|`.
#[derive(Clone)]
pub struct Penalties {
    /// Penalty for a one-pixel step.
    pub p1: u16,
    /// `p2_table[|I(p) − I(p−r)|]`: P2 for that grey-level step, never below P1.
    pub p2_table: [u16; 256],
}

impl Penalties {
    /// Clamps P2 so that `paths · (255 + P2)` fits `u16` (no sum can saturate), and builds the
    /// gradient table `P2 / (1 + |ΔI| / scale)` (`scale = 0`: constant).
    pub fn new(p1: u16, p2: u16, gradient_scale: f32, paths: u32) -> Self {
        let p2_max = (u16::MAX as u32 / paths.max(1)).saturating_sub(256) as u16;
        let p2 = p2.min(p2_max).max(1);
        let p1 = p1.min(p2).max(1);
        let mut p2_table = [p2; 256];
        if gradient_scale > 0.0 {
            for (g, v) in p2_table.iter_mut().enumerate() {
                *v = ((p2 as f32 / (1.0 + g as f32 / gradient_scale)) as u16).max(p1);
            }
        }
        Penalties { p1, p2_table }
    }
}

/// Aggregates along `paths` (4 or 8) directions. `bases` (one per pixel, or `None` for all 0) and
/// `k` say which disparities each pixel searches; `guide` is the left image, for adaptive P2.
///
/// With `store_costs`, whichever sweep reaches a row first computes its cost row into a volume of
/// `w·h·k` bytes and the other sweep reads it there, so costs are computed once, half on each
/// thread; without it each sweep computes every row itself (no volume beyond `S`, for a full
/// search whose memory bound leaves no room for one).
///
/// `S`, `min_sum` and the volume are made in `spare`'s memory when it holds enough; the volume
/// is given back there, `S` and `min_sum` with [`Aggregated::recycle`].
#[allow(clippy::too_many_arguments)]
pub fn aggregate(
    cost: &dyn CostRows,
    guide: &Raster<u8>,
    bases: Option<&[u16]>,
    k: usize,
    paths: u32,
    penalties: &Penalties,
    store_costs: bool,
    spare: &mut Workspace,
) -> Aggregated {
    let (w, h) = (cost.width(), cost.height());
    // None of them is read before a sweep writes it (see `Row::visited`).
    let mut s = buffer::reuse(std::mem::take(&mut spare.aggregated), w * h * k);
    let mut min_sum = buffer::reuse(std::mem::take(&mut spare.min_sum), w * h);
    let mut volume = if store_costs {
        buffer::reuse(std::mem::take(&mut spare.costs), w * h * k)
    } else {
        // No volume this time: a kept one would be held beyond the memory bound.
        spare.costs = Vec::new();
        Vec::new()
    };
    {
        let mut cost_rows = volume.chunks_mut(w * k);
        let rows: Vec<Mutex<Row>> = s
            .chunks_mut(w * k)
            .zip(min_sum.chunks_mut(w))
            .map(|(s, min_sum)| {
                Mutex::new(Row {
                    visited: false,
                    s,
                    min_sum,
                    costs: cost_rows.next(),
                })
            })
            .collect();
        let sweep = |forward: bool| {
            let sweep = Sweep {
                cost,
                stored_costs: store_costs,
                guide,
                bases,
                k,
                diagonals: paths == 8,
                pen: penalties,
                forward,
            };
            run_sweep(&sweep, &rows)
        };
        rayon::join(|| sweep(true), || sweep(false));
    }
    if store_costs {
        spare.give_back_costs(volume);
    }
    Aggregated {
        width: w,
        height: h,
        k,
        s,
        min_sum,
        paths,
    }
}

/// Bytes [`aggregate`] allocates for an image of `w × h` with `k` disparities (both sweeps).
pub fn working_bytes(w: usize, h: usize, k: usize, store_costs: bool) -> usize {
    let volume = w * h * k * (2 + store_costs as usize) + w * h * 2;
    // Recomputed costs, two rows of three directions' path costs, the row path's two pixels, the
    // entry costs and the re-indexing scratch, and the per-pixel minima.
    let per_sweep = w * k + 2 * 3 * w * (k + 2 * PAD) * 2 + 4 * (k + 2 * PAD) * 2 + 3 * 2 * w * 2;
    volume + 2 * per_sweep
}

/// One image row shared by the two sweeps: its slices of `S` and `min_sum`, and of the stored
/// cost volume.
struct Row<'r> {
    /// Whether a sweep has been here. The first one computes the row's costs (when stored) and
    /// writes `S` and `min_sum` without reading them, the second adds to them. Writing first
    /// matters: on fresh zeroed pages a read maps the shared zero page, and the write after it
    /// must then be made visible to every core (an inter-processor interrupt per page, a VM exit
    /// under virtualisation: 7–10 % of the matcher's time in `perf` on a 2-core VM).
    visited: bool,
    /// `S` of the row.
    s: &'r mut [u16],
    /// `Σ_r min_d L_r` of the row.
    min_sum: &'r mut [u16],
    /// The row's costs when they are stored (see [`aggregate`]).
    costs: Option<&'r mut [u8]>,
}

type RowLocks<'r> = [Mutex<Row<'r>>];

crate::avx2_variant!(fn run_sweep<'a, 'b, 'r>(sweep: &'b Sweep<'a>, rows: &'b RowLocks<'r>) => sweep_body);

#[inline(always)]
fn sweep_body(sweep: &Sweep<'_>, rows: &RowLocks<'_>) {
    // The usual windows (coarse-to-fine's 16 and 32) compiled at their length: the recurrence's
    // blocks and slices are then of constant size, without the per-pixel bounds and tail logic.
    match sweep.k {
        16 => sweep.run::<16>(rows),
        32 => sweep.run::<32>(rows),
        _ => sweep.run::<0>(rows),
    }
}

struct Sweep<'a> {
    cost: &'a dyn CostRows,
    /// Whether the rows carry a stored cost row ([`Row::costs`]).
    stored_costs: bool,
    guide: &'a Raster<u8>,
    bases: Option<&'a [u16]>,
    k: usize,
    diagonals: bool,
    pen: &'a Penalties,
    forward: bool,
}

/// `FAR` values kept on each side of a pixel's path costs in a [`PathRow`]: a neighbour whose
/// window starts up to `PAD − 1` disparities away from the pixel's is read in place, as one slice,
/// instead of being copied into the pixel's window first.
const PAD: usize = LANES;

/// One path direction's costs for a whole row: per pixel `PAD` × `FAR`, its `k` path costs, then
/// `PAD` × `FAR` again (see [`PathRow::view`]); and each pixel's smallest path cost.
struct PathRow {
    l: Vec<u16>,
    min: Vec<u16>,
    k: usize,
}

impl PathRow {
    fn new(w: usize, k: usize) -> Self {
        PathRow {
            l: vec![FAR; w * (k + 2 * PAD)],
            min: vec![0; w],
            k,
        }
    }

    /// The `k` path costs of pixel `x`, to be written.
    #[inline(always)]
    fn window_mut(&mut self, x: usize) -> &mut [u16] {
        let stride = self.k + 2 * PAD;
        &mut self.l[x * stride + PAD..x * stride + PAD + self.k]
    }

    /// Pixel `x`'s path costs seen from a pixel whose window starts `shift` disparities higher:
    /// `k + 2` values, entry `j` the cost at the other pixel's disparity index `j − 1` (`FAR`
    /// outside pixel `x`'s window), or `None` when the windows are `PAD` or more apart.
    #[inline(always)]
    fn view(&self, x: usize, shift: isize) -> Option<&[u16]> {
        if shift.unsigned_abs() >= PAD {
            return None;
        }
        let from = (x * (self.k + 2 * PAD) + PAD - 1).wrapping_add_signed(shift);
        self.l.get(from..from + self.k + 2)
    }
}

impl Sweep<'_> {
    /// The sweep over every row. `K`: the window's length `self.k` when known at compile time, 0
    /// otherwise.
    #[inline(always)]
    fn run<const K: usize>(&self, rows: &RowLocks<'_>) {
        let (w, h, k) = (self.cost.width(), self.cost.height(), self.k);
        let mut scratch = Vec::new();
        // The paths from the previous row, in the row before (`prev`) and in this one (`cur`):
        // 0 vertical, 1 and 2 the diagonals.
        let ndir = if self.diagonals { 3 } else { 1 };
        let mut prev: Vec<PathRow> = (0..ndir).map(|_| PathRow::new(w, k)).collect();
        let mut cur: Vec<PathRow> = (0..ndir).map(|_| PathRow::new(w, k)).collect();
        // The path along the row: the previous pixel's and the current pixel's costs.
        let mut along = AlongRow {
            prev: PathRow::new(1, k),
            cur: PathRow::new(1, k),
            min: 0,
        };
        // A path that enters the image here starts from zeros (then L = C).
        let mut start = vec![0u16; k + 2];
        start[0] = FAR;
        start[k + 1] = FAR;
        let start = &start[..];
        // A neighbour's costs re-indexed to the pixel's window, when the two are far apart.
        let mut aligned = vec![FAR; k + 2];

        for yi in 0..h {
            let y = if self.forward { yi } else { h - 1 - yi };
            // The row the sweep came from.
            let prev_y = match (yi, self.forward) {
                (0, _) => None,
                (_, true) => Some(y - 1),
                (_, false) => Some(y + 1),
            };
            let row_bases = self.bases.map(|b| &b[y * w..(y + 1) * w]);
            let prev_bases = match (self.bases, prev_y) {
                (Some(b), Some(py)) => Some(&b[py * w..(py + 1) * w]),
                _ => None,
            };
            let g = self.guide.row(y);
            let gp = prev_y.map(|py| self.guide.row(py));
            if !self.stored_costs {
                // Outside the lock, so that the two sweeps never wait on each other's costs.
                scratch.resize(w * k, 0);
                self.cost.row(y, row_bases, k, &mut scratch);
            }

            let Ok(mut guard) = rows[y].lock() else {
                // A panic on the other sweep poisoned the lock; it propagates from rayon::join.
                return;
            };
            let Row {
                visited,
                s: s_row,
                min_sum: min_row,
                costs: stored,
            } = &mut *guard;
            let first = !*visited;
            *visited = true;
            let costs: &[u8] = match stored {
                Some(row) => {
                    if first {
                        self.cost.row(y, row_bases, k, row);
                    }
                    row
                }
                None => &scratch,
            };
            let inputs = RowInputs {
                costs,
                first,
                g,
                gp,
                row_bases,
                prev_bases,
                start,
            };
            let paths = PathRows {
                prev: &prev,
                cur: &mut cur,
                along: &mut along,
                aligned: &mut aligned,
            };
            if self.diagonals {
                self.row_paths::<3, K>(&inputs, paths, s_row, min_row);
            } else {
                self.row_paths::<1, K>(&inputs, paths, s_row, min_row);
            }
            drop(guard);
            std::mem::swap(&mut prev, &mut cur);
        }
    }
}

/// What a sweep's paths read of the current and the previous row.
struct RowInputs<'a> {
    /// The row's costs, `k` per pixel.
    costs: &'a [u8],
    /// Whether this sweep is the first here: it writes the row's sums, the second adds to them.
    first: bool,
    /// The guide image's row and the previous row (`None` on the sweep's first row).
    g: &'a [u8],
    gp: Option<&'a [u8]>,
    /// The windows' starts in the row and in the previous row, with coarse-to-fine.
    row_bases: Option<&'a [u16]>,
    prev_bases: Option<&'a [u16]>,
    /// Path costs of a path that enters the image (zeros, `FAR` at both ends).
    start: &'a [u16],
}

/// The path along the row: the previous pixel's costs and their minimum, and the current
/// pixel's.
struct AlongRow {
    prev: PathRow,
    cur: PathRow,
    min: u16,
}

/// A sweep's path costs while it works on a row: the paths from the previous row (vertical and
/// diagonals) there and here, the path along the row, and scratch for re-indexing a neighbour.
struct PathRows<'p> {
    prev: &'p [PathRow],
    cur: &'p mut [PathRow],
    along: &'p mut AlongRow,
    aligned: &'p mut [u16],
}

impl Sweep<'_> {
    /// Every path of one row, pixel by pixel in the sweep's direction: along the row (each pixel
    /// continues from the one before it), then the first `NDIR` of the vertical path and the
    /// two diagonals (x − step, x + step), which read only the previous row. Writes or adds
    /// (`rows.first`) the path costs into `s_row` and their minima into `min_row`.
    ///
    /// All paths of a pixel in one loop: its costs, sums and minima are read and written once
    /// rather than once per direction, and the processor overlaps the row path's chain of
    /// dependent steps with the other paths' independent ones.
    #[inline(always)]
    fn row_paths<const NDIR: usize, const K: usize>(
        &self,
        rows: &RowInputs<'_>,
        paths: PathRows<'_>,
        s_row: &mut [u16],
        min_row: &mut [u16],
    ) {
        let w = self.cost.width();
        let k = if K > 0 { K } else { self.k };
        let step_x: isize = if self.forward { 1 } else { -1 };
        let p1 = self.pen.p1;
        let PathRows {
            prev,
            cur,
            along,
            aligned,
        } = paths;
        let (prev, cur) = (&prev[..NDIR], &mut cur[..NDIR]);
        for xi in 0..w {
            let x = if self.forward { xi } else { w - 1 - xi };
            let c = &rows.costs[x * k..(x + 1) * k];
            let sum = &mut s_row[x * k..(x + 1) * k];
            let (src, minprev, p2) = if xi == 0 {
                (rows.start, 0, self.pen.p2_table[0])
            } else {
                let xq = (x as isize - step_x) as usize;
                let shift = rows.row_bases.map_or(0, |b| b[x] as isize - b[xq] as isize);
                let p2 = self.pen.p2_table[rows.g[x].abs_diff(rows.g[xq]) as usize];
                let src = view_or_align(&along.prev, 0, shift, aligned);
                (src, along.min, p2)
            };
            let out = along.cur.window_mut(0);
            let m = if rows.first {
                step::<true, K>(c, src, minprev, p1, p2, out, sum)
            } else {
                step::<false, K>(c, src, minprev, p1, p2, out, sum)
            };
            along.min = m;
            std::mem::swap(&mut along.prev, &mut along.cur);
            let mut minima = if rows.first {
                m
            } else {
                min_row[x].saturating_add(m)
            };
            for (dir, off) in [0isize, -1, 1].into_iter().take(NDIR).enumerate() {
                let (before, now) = (&prev[dir], &mut cur[dir]);
                let xq = x as isize + off * step_x;
                let m = match rows.gp {
                    Some(gp) if xq >= 0 && (xq as usize) < w => {
                        let xq = xq as usize;
                        let p2 = self.pen.p2_table[rows.g[x].abs_diff(gp[xq]) as usize];
                        let shift = match (rows.row_bases, rows.prev_bases) {
                            (Some(b), Some(pb)) => b[x] as isize - pb[xq] as isize,
                            _ => 0,
                        };
                        let src = view_or_align(before, xq, shift, aligned);
                        let minprev = before.min[xq];
                        step::<false, K>(c, src, minprev, p1, p2, now.window_mut(x), sum)
                    }
                    _ => {
                        let p2 = self.pen.p2_table[0];
                        step::<false, K>(c, rows.start, 0, p1, p2, now.window_mut(x), sum)
                    }
                };
                now.min[x] = m;
                minima = minima.saturating_add(m);
            }
            min_row[x] = minima;
        }
    }
}

/// Pixel `x` of `row` seen from a window `shift` disparities higher ([`PathRow::view`]); when the
/// windows are too far apart for that, the costs copied into `scratch` at their new indices.
#[inline(always)]
fn view_or_align<'b>(
    row: &'b PathRow,
    x: usize,
    shift: isize,
    scratch: &'b mut [u16],
) -> &'b [u16] {
    if let Some(view) = row.view(x, shift) {
        return view;
    }
    let k = row.k as isize;
    let own = row.view(x, 0).unwrap_or(&[]);
    // scratch[j] = own[j + shift] for j + shift in 1..=k, FAR elsewhere.
    scratch.fill(FAR);
    let lo = (1 - shift).max(0);
    let hi = (k + 1 - shift).min(k + 2);
    if lo < hi {
        let (lo, hi) = (lo as usize, hi as usize);
        let from = (lo as isize + shift) as usize;
        if let (Some(dst), Some(src)) = (scratch.get_mut(lo..hi), own.get(from..from + (hi - lo))) {
            dst.copy_from_slice(src);
        }
    }
    scratch
}

/// One recurrence step (eq. 3.3) for every disparity of a pixel; adds into `sum` (`ASSIGN`:
/// overwrites it), returns the minimum of the new path costs. `prev` holds `k + 2` values, the
/// neighbour's costs at the pixel's disparity indices −1..=k (`FAR` where the neighbour has
/// none); `out` receives the `k` new ones.
#[inline(always)]
fn step<const ASSIGN: bool, const K: usize>(
    cost: &[u8],
    prev: &[u16],
    minprev: u16,
    p1: u16,
    p2: u16,
    out: &mut [u16],
    sum: &mut [u16],
) -> u16 {
    let k = if K > 0 { K } else { cost.len() };
    let (cost, prev, out, sum) = (&cost[..k], &prev[..k + 2], &mut out[..k], &mut sum[..k]);
    let jump = minprev.saturating_add(p2);
    // Whole blocks of 16 lanes first (one AVX2 register each), then the rest one by one: a
    // single loop would leave windows shorter than the vectoriser's unrolled width all scalar.
    let blocks = k / LANES * LANES;
    let mut best = [u16::MAX; LANES];
    for b in (0..blocks).step_by(LANES) {
        let v = block(cost, prev, b, minprev, p1, jump, &mut best);
        out[b..b + LANES].copy_from_slice(&v);
        for (s, v) in sum[b..b + LANES].iter_mut().zip(v) {
            *s = if ASSIGN { v } else { s.saturating_add(v) };
        }
    }
    let tail = k - blocks;
    if tail > 0 && blocks > 0 {
        // The last `tail` disparities as one more whole block, the one ending at `k`: it overlaps
        // the block before by `LANES − tail` lanes, which it recomputes to the same values (same
        // inputs) and leaves out of `sum`, so that they are not added twice. A scalar tail costs
        // as much as two blocks (the coarse level's and a full search's `k` are rarely multiples
        // of 16).
        let b = k - LANES;
        let v = block(cost, prev, b, minprev, p1, jump, &mut best);
        out[b..k].copy_from_slice(&v);
        let new_from = LANES - tail;
        for (i, (s, v)) in sum[b..k].iter_mut().zip(v).enumerate() {
            // All ones on the lanes this block adds, zero on those the block before wrote.
            let new = ((i >= new_from) as u16).wrapping_neg();
            *s = if ASSIGN {
                (*s & !new) | (v & new)
            } else {
                s.saturating_add(v & new)
            };
        }
        return best.iter().copied().min().unwrap_or(u16::MAX);
    }
    // Fewer than `LANES` disparities in all: one by one.
    let mut best = best.iter().copied().min().unwrap_or(u16::MAX);
    for i in blocks..k {
        let t = prev[i + 1]
            .min(prev[i].saturating_add(p1))
            .min(prev[i + 2].saturating_add(p1))
            .min(jump);
        let v = (cost[i] as u16).saturating_add(t - minprev);
        out[i] = v;
        sum[i] = if ASSIGN { v } else { sum[i].saturating_add(v) };
        best = best.min(v);
    }
    best
}

/// The recurrence (eq. 3.3) for the `LANES` disparities from index `b` of a [`step`]: the new
/// path costs, each also folded into `best`.
#[inline(always)]
fn block(
    cost: &[u8],
    prev: &[u16],
    b: usize,
    minprev: u16,
    p1: u16,
    jump: u16,
    best: &mut [u16; LANES],
) -> [u16; LANES] {
    let c: &[u8; LANES] = cost[b..b + LANES].try_into().unwrap_or(&[0; LANES]);
    let lower: &[u16; LANES] = prev[b..b + LANES].try_into().unwrap_or(&[0; LANES]);
    let same: &[u16; LANES] = prev[b + 1..b + 1 + LANES].try_into().unwrap_or(&[0; LANES]);
    let upper: &[u16; LANES] = prev[b + 2..b + 2 + LANES].try_into().unwrap_or(&[0; LANES]);
    let mut v = [0u16; LANES];
    for i in 0..LANES {
        let t = same[i]
            .min(lower[i].saturating_add(p1))
            .min(upper[i].saturating_add(p1))
            .min(jump);
        // t ≥ minprev (minprev is the minimum of prev's window), so this cannot wrap.
        v[i] = (c[i] as u16).saturating_add(t - minprev);
        best[i] = best[i].min(v[i]);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Costs given by a function of (x, y, disparity), for every disparity.
    struct FnCost<F: Fn(usize, usize, usize) -> u8 + Sync> {
        w: usize,
        h: usize,
        at: F,
    }
    impl<F: Fn(usize, usize, usize) -> u8 + Sync> CostRows for FnCost<F> {
        fn width(&self) -> usize {
            self.w
        }
        fn height(&self) -> usize {
            self.h
        }
        fn row(&self, y: usize, bases: Option<&[u16]>, k: usize, out: &mut [u8]) {
            for x in 0..self.w {
                let base = bases.map_or(0, |b| b[x] as usize);
                for i in 0..k {
                    out[x * k + i] = (self.at)(x, y, base + i);
                }
            }
        }
    }

    /// A cost that prefers disparity `d` everywhere except pixel (5, 5), which prefers `d + 5`.
    fn toy(w: usize, h: usize, d: usize) -> FnCost<impl Fn(usize, usize, usize) -> u8 + Sync> {
        FnCost {
            w,
            h,
            at: move |x, y, disparity| {
                let want = if (x, y) == (5, 5) { d + 5 } else { d };
                if disparity == want {
                    0
                } else {
                    40
                }
            },
        }
    }

    fn argmin(v: &[u16]) -> usize {
        (0..v.len()).min_by_key(|&i| v[i]).unwrap_or(0)
    }

    #[test]
    fn smoothness_overrides_a_single_outlier_and_keeps_sums_unsaturated() {
        let toy = toy(12, 11, 3);
        let guide = Raster::filled(12, 11, 0u8);
        for paths in [4, 8] {
            let pen = Penalties::new(10, 100, 0.0, paths);
            let a = aggregate(
                &toy,
                &guide,
                None,
                10,
                paths,
                &pen,
                paths == 8,
                &mut Workspace::default(),
            );
            for p in 0..12 * 11 {
                assert_eq!(argmin(&a.s[p * 10..p * 10 + 10]), 3, "pixel {p}");
            }
            // Eq. 3.5: where every path agrees, min S equals the sum of the path minima.
            let p = 2 * 12 + 9;
            assert_eq!(a.s[p * 10 + 3], a.min_sum[p]);
            assert!(a.s.iter().all(|&v| v < u16::MAX));
        }
    }

    /// Pseudo-random costs in 0..60.
    fn noise(x: usize, y: usize, d: usize) -> u8 {
        ((x * 7919 + y * 104_729 + d * 1_299_709) % 1021 % 60) as u8
    }

    /// Eq. 3.3–3.4 written out plainly (u32, one path at a time): `S` and `Σ_r min_d L_r`.
    /// Each pixel `p` searches `bases[p]..bases[p] + k` (all 0 without `bases`); a neighbour's
    /// path cost at a disparity outside its own window counts as infinite.
    fn reference(
        cost: &FnCost<impl Fn(usize, usize, usize) -> u8 + Sync>,
        guide: &Raster<u8>,
        bases: Option<&[u16]>,
        k: usize,
        paths: u32,
        pen: &Penalties,
    ) -> (Vec<u32>, Vec<u32>) {
        let (w, h) = (cost.w as isize, cost.h as isize);
        let mut dirs = vec![(1, 0), (-1, 0), (0, 1), (0, -1)];
        if paths == 8 {
            dirs.extend([(1, 1), (-1, 1), (1, -1), (-1, -1)]);
        }
        let idx = |x: isize, y: isize| (y * w + x) as usize;
        let base = |p: usize| bases.map_or(0, |b| b[p] as usize);
        let (mut s, mut min_sum) = (
            vec![0u32; (w * h) as usize * k],
            vec![0u32; (w * h) as usize],
        );
        for (dx, dy) in dirs {
            let mut l = vec![0u32; (w * h) as usize * k];
            // Visit p after p − r: along the row when the path is horizontal, else row by row.
            let ys: Vec<isize> = if dy >= 0 {
                (0..h).collect()
            } else {
                (0..h).rev().collect()
            };
            let xs: Vec<isize> = if dx >= 0 {
                (0..w).collect()
            } else {
                (0..w).rev().collect()
            };
            for &y in &ys {
                for &x in &xs {
                    let (qx, qy) = (x - dx, y - dy);
                    let p = idx(x, y);
                    let c = |i: usize| (cost.at)(x as usize, y as usize, base(p) + i) as u32;
                    if qx < 0 || qy < 0 || qx >= w || qy >= h {
                        for i in 0..k {
                            l[p * k + i] = c(i);
                        }
                        continue;
                    }
                    let q = idx(qx, qy);
                    let prev = &l[q * k..(q + 1) * k].to_vec();
                    let m = *prev.iter().min().unwrap();
                    // The neighbour's path cost at an absolute disparity, infinite outside its window.
                    let at = |d: isize| -> u32 {
                        let i = d - base(q) as isize;
                        if (0..k as isize).contains(&i) {
                            prev[i as usize]
                        } else {
                            u32::MAX / 2
                        }
                    };
                    let grad = guide
                        .get(x as usize, y as usize)
                        .abs_diff(*guide.get(qx as usize, qy as usize));
                    let p2 = pen.p2_table[grad as usize] as u32;
                    let p1 = pen.p1 as u32;
                    for i in 0..k {
                        let d = (base(p) + i) as isize;
                        let t = at(d).min(at(d - 1) + p1).min(at(d + 1) + p1).min(m + p2);
                        l[p * k + i] = c(i) + t - m;
                    }
                }
            }
            for p in 0..(w * h) as usize {
                let lp = &l[p * k..(p + 1) * k];
                min_sum[p] += lp.iter().min().unwrap();
                for d in 0..k {
                    s[p * k + d] += lp[d];
                }
            }
        }
        (s, min_sum)
    }

    /// `aggregate`, with stored and with recomputed costs, gives exactly [`reference`]'s `S` and
    /// `Σ_r min_d L_r`.
    fn assert_matches_reference(
        cost: &FnCost<impl Fn(usize, usize, usize) -> u8 + Sync>,
        guide: &Raster<u8>,
        bases: Option<&[u16]>,
        k: usize,
        paths: u32,
        pen: &Penalties,
    ) {
        let (s, min_sum) = reference(cost, guide, bases, k, paths, pen);
        let widen = |v: &[u16]| v.iter().map(|&x| x as u32).collect::<Vec<_>>();
        for store in [false, true] {
            let a = aggregate(
                cost,
                guide,
                bases,
                k,
                paths,
                pen,
                store,
                &mut Workspace::default(),
            );
            assert_eq!(widen(&a.s), s, "k {k}, paths {paths}, stored {store}");
            assert_eq!(
                widen(&a.min_sum),
                min_sum,
                "k {k}, paths {paths}, stored {store}"
            );
        }
    }

    #[test]
    fn both_sweeps_give_the_plain_recurrence_with_stored_or_recomputed_costs() {
        // Fewer disparities than a 16-lane block (one by one), whole blocks (16 and 32 also as
        // the sweeps compiled at those lengths), and whole blocks with a last block overlapping
        // the one before by 11, 1 and 15 lanes.
        let (w, h) = (23, 9);
        let noise = FnCost { w, h, at: noise };
        let guide = Raster::from_fn(w, h, |x, y| ((x * 29 + y * 13) % 17 * 15) as u8);
        for k in [7, 16, 21, 31, 32, 33] {
            for paths in [4, 8] {
                let pen = Penalties::new(10, 100, 16.0, paths);
                assert_matches_reference(&noise, &guide, None, k, paths, &pen);
            }
        }
    }

    #[test]
    fn per_pixel_windows_give_the_plain_recurrence_at_every_offset_between_neighbours() {
        // Neighbouring windows from 0 up to 45 disparities apart (read in place below 16, copied
        // beyond that, disjoint beyond k); k = 21 and 37 end with a block overlapping the one
        // before, k = 16 and 32 do not (and take the sweeps compiled at those lengths).
        let (w, h) = (19, 11);
        let noise = FnCost { w, h, at: noise };
        let guide = Raster::from_fn(w, h, |x, y| ((x * 31 + y * 7) % 13 * 19) as u8);
        let bases: Vec<u16> = (0..w * h)
            .map(|p| match p % 7 {
                0 => 45,
                1 | 2 => (p % 5) as u16,
                3 => 17,
                _ => (p % 23) as u16,
            })
            .collect();
        for (k, paths) in [(16, 8), (21, 8), (32, 8), (32, 4), (37, 8)] {
            let pen = Penalties::new(10, 100, 16.0, paths);
            assert_matches_reference(&noise, &guide, Some(&bases), k, paths, &pen);
        }
    }

    #[test]
    fn huge_p2_is_clamped_so_nothing_saturates() {
        let toy = toy(9, 9, 2);
        let guide = Raster::filled(9, 9, 0u8);
        let pen = Penalties::new(u16::MAX, u16::MAX, 0.0, 8);
        assert!(8 * (255 + pen.p2_table[0] as u32) <= u16::MAX as u32);
        let a = aggregate(
            &toy,
            &guide,
            None,
            6,
            8,
            &pen,
            false,
            &mut Workspace::default(),
        );
        assert!(a.s.iter().all(|&v| v < u16::MAX));
        for p in 0..81 {
            assert_eq!(argmin(&a.s[p * 6..p * 6 + 6]), 2);
        }
    }

    #[test]
    fn per_pixel_windows_give_the_same_winner_as_the_full_search() {
        let toy = toy(14, 8, 6);
        let guide = Raster::filled(14, 8, 0u8);
        let pen = Penalties::new(10, 100, 0.0, 8);
        // Windows of 5 that all contain 6 but start at different places.
        let bases: Vec<u16> = (0..14 * 8).map(|p| (2 + p % 3) as u16).collect();
        let a = aggregate(
            &toy,
            &guide,
            Some(&bases),
            5,
            8,
            &pen,
            true,
            &mut Workspace::default(),
        );
        for (p, &base) in bases.iter().enumerate() {
            if p == 5 * 14 + 5 {
                continue;
            }
            assert_eq!(
                base as usize + argmin(&a.s[p * 5..p * 5 + 5]),
                6,
                "pixel {p}"
            );
        }
    }
}
