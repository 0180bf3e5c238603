//! Caps on what one glTF asset may make the loader allocate, and the running memory budget that
//! enforces them. Every cap is checked against the counts the file *claims* before anything of
//! that size is allocated, so a 100-byte file that claims a billion vertices costs nothing.

use crate::error::{Error, Result};

/// Configurable caps for loading one artefact. Defaults suit interactive compositing on a desktop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadLimits {
    /// Largest total number of vertices after flattening the node hierarchy (every node instance
    /// of a mesh counts). Default 8 Mi.
    pub max_vertices: u64,
    /// Largest total number of triangles after flattening and strip/fan conversion. Default 8 Mi.
    pub max_triangles: u64,
    /// Largest width or height of one texture, in pixels. Default 8192.
    pub max_texture_side: u32,
    /// Largest total of bytes the loader may hold: file buffers, decoded textures and the output
    /// vertex and index data together. Default 2 GiB.
    pub max_total_bytes: u64,
    /// Largest number of nodes visited while flattening the hierarchy. Default 1 Mi.
    pub max_nodes: u64,
}

impl Default for LoadLimits {
    fn default() -> Self {
        LoadLimits {
            max_vertices: 8 << 20,
            max_triangles: 8 << 20,
            max_texture_side: 8192,
            max_total_bytes: 2 << 30,
            max_nodes: 1 << 20,
        }
    }
}

/// Bytes reserved so far against [`LoadLimits::max_total_bytes`].
#[derive(Debug)]
pub(crate) struct MemoryBudget {
    used: u64,
    cap: u64,
}

impl MemoryBudget {
    pub(crate) fn new(limits: &LoadLimits) -> Self {
        MemoryBudget {
            used: 0,
            cap: limits.max_total_bytes,
        }
    }

    /// Reserves `bytes` for `what`, before the allocation happens.
    ///
    /// # Errors
    /// `TooLarge` naming `what` when the running total would pass the cap.
    pub(crate) fn reserve(&mut self, what: &str, bytes: u64) -> Result<()> {
        let total = self.used.saturating_add(bytes);
        if total > self.cap {
            return Err(Error::TooLarge(format!(
                "{what} needs {bytes} bytes, which brings the artefact to {total} bytes, over the \
                 cap of {} bytes (LoadLimits::max_total_bytes)",
                self.cap
            )));
        }
        self.used = total;
        Ok(())
    }

    /// Bytes reserved so far.
    #[cfg(test)]
    pub(crate) fn used(&self) -> u64 {
        self.used
    }
}

/// `a × b` for sizes taken from a file, as a `TooLarge` error when it overflows.
pub(crate) fn mul(a: u64, b: u64, what: &str) -> Result<u64> {
    a.checked_mul(b)
        .ok_or_else(|| Error::TooLarge(format!("{what}: {a} × {b} overflows")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_refuses_past_the_cap_and_names_what() {
        let limits = LoadLimits {
            max_total_bytes: 100,
            ..LoadLimits::default()
        };
        let mut b = MemoryBudget::new(&limits);
        b.reserve("buffer 0", 60).unwrap();
        let e = b.reserve("texture 3", 50).unwrap_err();
        assert!(matches!(e, Error::TooLarge(_)));
        assert!(e.to_string().contains("texture 3"), "{e}");
        assert_eq!(b.used(), 60);
        b.reserve("rest", 40).unwrap();
        assert!(b.reserve("one more", u64::MAX).is_err());
    }

    #[test]
    fn mul_reports_overflow() {
        assert_eq!(mul(3, 4, "x").unwrap(), 12);
        assert!(matches!(mul(u64::MAX, 2, "x"), Err(Error::TooLarge(_))));
    }
}
