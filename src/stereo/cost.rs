//! The interface between matching costs and aggregation: one image row of costs at a time.
//!
//! Costs are `u8` on a 0–255 scale so that aggregation runs on `u16` lanes. They are computed row
//! by row on demand; aggregation stores them as a volume (1 byte per pixel and disparity, next to
//! its own 2) only when the memory bound leaves room for it (a narrow coarse-to-fine window, a
//! coarse level), so that a full search keeps the aggregated volume as the only one in memory.

/// Cost of a left pixel whose candidate match lies left of the right image's first column.
/// A constant lets the smoothness term decide there, which the L/R check later flags anyway.
pub const OUTSIDE_COST: u8 = 64;

/// How many of left pixel `x`'s disparities `base..base + k` land inside the right view
/// (`d ≤ x`); the others cost [`OUTSIDE_COST`].
#[inline(always)]
pub fn inside_right_view(x: usize, base: usize, k: usize) -> usize {
    if x >= base {
        (x - base + 1).min(k)
    } else {
        0
    }
}

/// A matching cost that can fill one row of costs.
pub trait CostRows: Sync {
    /// Image width in pixels.
    fn width(&self) -> usize;
    /// Image height in pixels.
    fn height(&self) -> usize;
    /// Fills `out` (`width × k` values, pixel-major) with the costs of row `y` for disparities
    /// `bases[x] + i`, `i in 0..k`; `bases = None` means every base is 0. Aggregation may call it
    /// while it holds a row lock, so it must not wait on other rayon tasks.
    fn row(&self, y: usize, bases: Option<&[u16]>, k: usize, out: &mut [u8]);
}
