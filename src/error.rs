//! The library's one error type, and how each kind of error maps to a C status code.

use std::path::Path;

/// Every fallible function in Parallax returns this.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong. Each variant carries a message that names the offending input.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An argument is out of its documented range (zero size, NaN, near ≥ far, …).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// Two inputs that must agree in size do not (left/right images, a buffer and its image).
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
    /// An input exceeds a configured cap (image pixels, vertex count, memory).
    #[error("too large: {0}")]
    TooLarge(String),
    /// A file or buffer is malformed or not in the expected format.
    #[error("format error: {0}")]
    Format(String),
    /// Reading or writing a file failed.
    #[error("I/O error on {path}: {source}")]
    Io {
        /// The file that could not be read or written.
        path: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The GPU could not be used (no adapter, device lost, out of GPU memory, …).
    #[error("GPU error: {0}")]
    Gpu(String),
    /// The input asks for something this build or this library does not support.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// A product cannot be computed because an input it needs was never given.
    #[error("not available: {0}")]
    NotAvailable(String),
    /// The caller cancelled a long operation.
    #[error("cancelled: {0}")]
    Cancelled(String),
    /// A bug in Parallax: an invariant did not hold.
    #[error("internal error: {0}")]
    Internal(String),
}

impl Error {
    /// `Error::Io` for `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().display().to_string(),
            source,
        }
    }

    /// Shorthand for [`Error::InvalidArgument`].
    pub fn invalid(message: impl Into<String>) -> Self {
        Error::InvalidArgument(message.into())
    }

    /// Shorthand for [`Error::Format`].
    pub fn format(message: impl Into<String>) -> Self {
        Error::Format(message.into())
    }

    /// The C status code this error is reported as.
    pub fn status(&self) -> Status {
        match self {
            Error::InvalidArgument(_) => Status::InvalidArgument,
            Error::SizeMismatch(_) => Status::SizeMismatch,
            Error::TooLarge(_) => Status::TooLarge,
            Error::Format(_) => Status::Format,
            Error::Io { .. } => Status::Io,
            Error::Gpu(_) => Status::Gpu,
            Error::Unsupported(_) => Status::Unsupported,
            Error::NotAvailable(_) => Status::NotAvailable,
            Error::Cancelled(_) => Status::Cancelled,
            Error::Internal(_) => Status::Internal,
        }
    }
}

/// Result of every fallible C function (`plx_status` in C).
///
/// `PLX_STATUS_OK` is zero; every other value is an error whose detail
/// `plx_last_error_message` returns.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Status {
    /// Success.
    Ok = 0,
    /// A required pointer argument was NULL.
    NullArgument = 1,
    /// An argument is out of its documented range.
    InvalidArgument = 2,
    /// Two inputs that must agree in size do not, or a caller buffer is too small.
    SizeMismatch = 3,
    /// An input exceeds a configured cap.
    TooLarge = 4,
    /// Malformed data or an unknown format.
    Format = 5,
    /// A file could not be read or written.
    Io = 6,
    /// Something this build does not support (a missing feature, a glTF extension, …).
    Unsupported = 7,
    /// The GPU could not be used.
    Gpu = 8,
    /// The product asked for needs an input that was never given.
    NotAvailable = 9,
    /// A Rust panic was caught at the C boundary; the handle may be in an unspecified state.
    Panic = 10,
    /// A bug in Parallax.
    Internal = 11,
    /// The host's progress callback asked to stop.
    Cancelled = 12,
}

impl Status {
    /// A static, NUL-free description of the status.
    pub fn description(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::NullArgument => "a required pointer argument was NULL",
            Status::InvalidArgument => "invalid argument",
            Status::SizeMismatch => "size mismatch",
            Status::TooLarge => "input too large",
            Status::Format => "malformed data or unknown format",
            Status::Io => "file input/output error",
            Status::Unsupported => "unsupported",
            Status::Gpu => "GPU error",
            Status::NotAvailable => "not available: a required input is missing",
            Status::Panic => "internal panic caught at the C boundary",
            Status::Internal => "internal error",
            Status::Cancelled => "cancelled by the host",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_error_maps_to_a_distinct_non_ok_status() {
        let errors = [
            Error::invalid("x"),
            Error::SizeMismatch("x".into()),
            Error::TooLarge("x".into()),
            Error::format("x"),
            Error::io("f", std::io::Error::other("x")),
            Error::Gpu("x".into()),
            Error::Unsupported("x".into()),
            Error::NotAvailable("x".into()),
            Error::Cancelled("x".into()),
            Error::Internal("x".into()),
        ];
        let mut seen = std::collections::HashSet::new();
        for e in &errors {
            let s = e.status();
            assert_ne!(s, Status::Ok);
            assert!(seen.insert(s), "{s:?} used twice");
        }
    }

    #[test]
    fn io_error_message_names_the_file() {
        let e = Error::io(
            "/no/such.png",
            std::io::Error::from(std::io::ErrorKind::NotFound),
        );
        assert!(e.to_string().contains("/no/such.png"));
    }
}
