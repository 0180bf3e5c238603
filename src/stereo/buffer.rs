//! Large zeroed buffers for the matcher's volumes, backed by transparent huge pages where the
//! system allows them.
//!
//! A zeroed `Vec` of many megabytes comes straight from the kernel as untouched pages, and its
//! first write to each 4 KiB page is a page fault: for the aggregated volume of a 0.37 MP pair
//! (24 MB with a 32-disparity window) some 6 000 faults. Asking for huge pages
//! (`madvise(MADV_HUGEPAGE)`, Linux) before the first write turns them into a dozen 2 MiB faults
//! (measured in docs/stereo-eval.md, stop 23). Elsewhere, or where the system has transparent
//! huge pages off, the buffer is an ordinary `Vec`.
//!
//! A [`Workspace`] can keep those buffers between matches (see [`super::StereoMatcher`]): a
//! host matching a stream of frames then neither allocates them again nor has the kernel zero
//! their pages, some 20 MB per 0.35 MP frame.

/// A transparent huge page on x86-64 and most aarch64 kernels, bytes.
const HUGE_PAGE: usize = 2 << 20;

/// `len` copies of `T::zeroed()` in a `Vec` whose memory the kernel may back with huge pages.
pub fn zeroed<T: bytemuck::Zeroable + Clone>(len: usize) -> Vec<T> {
    let v = vec![T::zeroed(); len];
    advise_huge_pages(&v);
    v
}

/// A buffer of `len` values made from `spare`'s memory, its old values left in place (only the
/// part beyond `spare`'s length is zeroed), or a fresh [`zeroed`] one when `spare` holds too
/// little. Only for buffers that every user writes before it reads them.
pub fn reuse<T: bytemuck::Zeroable + Clone>(mut spare: Vec<T>, len: usize) -> Vec<T> {
    if spare.capacity() < len {
        // Freed first, so that the old and the new buffer are never held together.
        drop(spare);
        return zeroed(len);
    }
    spare.truncate(len);
    spare.resize(len, T::zeroed());
    spare
}

/// The matcher's large buffers, made from memory given back by an earlier step, level or match.
/// Each is written before it is read (so stale values from an earlier pair never reach a
/// result); an empty `Vec` until first used. The half-size level and the full-size level run one
/// after the other and share the buffers, so a kept workspace holds each buffer at the size of
/// the larger level's.
#[derive(Debug, Default)]
pub struct Workspace {
    /// Whether buffers given back are kept for the next use; `false` (the default, a one-off
    /// match) drops them at once, so that the peak memory is that of fresh buffers.
    keep: bool,
    /// The aggregated costs `S` ([`super::sgm::Aggregated::s`]).
    pub(crate) aggregated: Vec<u16>,
    /// The per-pixel sums of the paths' minima ([`super::sgm::Aggregated::min_sum`]).
    pub(crate) min_sum: Vec<u16>,
    /// The stored cost volume of the aggregation.
    pub(crate) costs: Vec<u8>,
    /// The census transforms of the left and the right view.
    pub(crate) census: [Vec<u64>; 2],
}

impl Workspace {
    /// A workspace that keeps what it is given back, for the next match.
    pub fn keeping() -> Self {
        Workspace {
            keep: true,
            ..Default::default()
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        fn held<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        held(&self.aggregated)
            + held(&self.min_sum)
            + held(&self.costs)
            + self.census.iter().map(held).sum::<usize>()
    }

    /// Takes back `S` and `min_sum` (kept, or dropped).
    pub fn give_back_aggregated(&mut self, aggregated: Vec<u16>, min_sum: Vec<u16>) {
        if self.keep {
            (self.aggregated, self.min_sum) = (aggregated, min_sum);
        }
    }

    /// Takes back the cost volume (kept, or dropped).
    pub fn give_back_costs(&mut self, costs: Vec<u8>) {
        if self.keep {
            self.costs = costs;
        }
    }

    /// Takes back the census transforms (kept, or dropped).
    pub fn give_back_census(&mut self, census: [Vec<u64>; 2]) {
        if self.keep {
            self.census = census;
        }
    }
}

/// Asks the kernel to back `v`'s whole 2 MiB-aligned pages with huge pages; a no-op for small
/// buffers and on systems without `madvise`. Only useful before the pages are first written.
fn advise_huge_pages<T>(v: &[T]) {
    let bytes = std::mem::size_of_val(v);
    // Below two huge pages a buffer may not hold a whole aligned one.
    if bytes < 2 * HUGE_PAGE {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        let start = v.as_ptr() as usize;
        let aligned = start.next_multiple_of(HUGE_PAGE);
        let end = (start + bytes) / HUGE_PAGE * HUGE_PAGE;
        if end > aligned {
            // SAFETY: [aligned, end) lies inside `v`'s allocation, which outlives the call;
            // MADV_HUGEPAGE only changes how the kernel backs those pages, never their contents,
            // and a failure (huge pages disabled) leaves them as they were.
            unsafe {
                libc::madvise(
                    aligned as *mut libc::c_void,
                    end - aligned,
                    libc::MADV_HUGEPAGE,
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_are_zeroed_and_writable_at_every_size() {
        for len in [0, 1, 4097, (5 << 20) + 3] {
            let mut v: Vec<u16> = zeroed(len);
            assert_eq!(v.len(), len);
            assert!(v.iter().all(|&x| x == 0));
            v.iter_mut().enumerate().for_each(|(i, x)| *x = i as u16);
            assert!(v.iter().enumerate().all(|(i, &x)| x == i as u16));
        }
    }

    #[test]
    fn reused_buffers_keep_their_memory_and_have_the_asked_length() {
        let spare: Vec<u16> = (0..100).collect();
        let ptr = spare.as_ptr();
        // Shorter: the same memory, the old values kept.
        let v = reuse(spare, 40);
        assert_eq!((v.len(), v.as_ptr()), (40, ptr));
        assert_eq!(v[39], 39);
        // Longer, within the capacity: the same memory, the new part zeroed.
        let v = reuse(v, 90);
        assert_eq!((v.len(), v.as_ptr()), (90, ptr));
        assert_eq!((v[39], v[40], v[89]), (39, 0, 0));
        // Beyond the capacity: a new zeroed buffer.
        let v = reuse(v, 1000);
        assert_eq!(v.len(), 1000);
        assert!(v.iter().all(|&x| x == 0));
    }

    #[test]
    fn only_a_keeping_workspace_holds_what_it_is_given_back() {
        let give = |ws: &mut Workspace| {
            ws.give_back_aggregated(vec![0; 10], vec![0; 4]);
            ws.give_back_costs(vec![0; 10]);
            ws.give_back_census([vec![0; 4], vec![0; 4]]);
        };
        let mut one_off = Workspace::default();
        give(&mut one_off);
        assert_eq!(one_off.bytes(), 0);
        let mut kept = Workspace::keeping();
        give(&mut kept);
        assert!(kept.bytes() >= 20 + 8 + 10 + 64);
    }
}
