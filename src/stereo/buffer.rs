//! Large zeroed buffers for the matcher's volumes, backed by transparent huge pages where the
//! system allows them.
//!
//! A zeroed `Vec` of many megabytes comes straight from the kernel as untouched pages, and its
//! first write to each 4 KiB page is a page fault: for the aggregated volume of a 0.37 MP pair
//! (24 MB with a 32-disparity window) some 6 000 faults. Asking for huge pages
//! (`madvise(MADV_HUGEPAGE)`, Linux) before the first write turns them into a dozen 2 MiB faults
//! (measured in docs/stereo-eval.md, stop 23). Elsewhere, or where the system has transparent
//! huge pages off, the buffer is an ordinary `Vec`.

/// A transparent huge page on x86-64 and most aarch64 kernels, bytes.
const HUGE_PAGE: usize = 2 << 20;

/// `len` copies of `T::zeroed()` in a `Vec` whose memory the kernel may back with huge pages.
pub fn zeroed<T: bytemuck::Zeroable + Clone>(len: usize) -> Vec<T> {
    let v = vec![T::zeroed(); len];
    advise_huge_pages(&v);
    v
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
}
