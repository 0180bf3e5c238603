//! The URI policy for buffers and images a glTF file refers to.
//!
//! A model is untrusted input, so a URI may only name:
//! - its own bytes, as a `data:` URI (base64 or percent-encoded), or
//! - a file inside the folder of the asset itself (or below it): a relative path with no absolute
//!   prefix, no drive letter, no `..` that climbs out of the folder, and no symbolic link that
//!   leads out of it.
//!
//! Network schemes (`http:`, `https:`, `ftp:`, …) and `file:` are refused: loading a model must
//! never reach outside the folder the caller pointed at.

use std::path::{Path, PathBuf};

use super::limits::MemoryBudget;
use crate::error::{Error, Result};

/// Where a URI's bytes come from, once the policy accepted it.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum UriTarget {
    /// Bytes embedded in the URI itself (already decoded).
    Data(Vec<u8>),
    /// A file inside the asset's folder.
    File(PathBuf),
}

/// Applies the policy to `uri` (as written in the file), decoding `data:` URIs under `budget`.
///
/// `base` is the folder of the asset; `None` when the asset came from memory, in which case only
/// `data:` URIs are accepted.
///
/// # Errors
/// `InvalidArgument` naming the URI for a refused scheme, an absolute path, a path escaping the
/// folder, or an external file with no base folder; `Format` for a malformed `data:` URI;
/// `TooLarge` when the decoded bytes would pass the memory cap.
pub(crate) fn resolve(
    uri: &str,
    base: Option<&Path>,
    what: &str,
    budget: &mut MemoryBudget,
) -> Result<UriTarget> {
    let shown = shorten(uri);
    if let Some(rest) = uri.strip_prefix("data:") {
        return decode_data_uri(rest, what, &shown, budget).map(UriTarget::Data);
    }
    if let Some(scheme) = scheme_of(uri) {
        return Err(Error::invalid(format!(
            "{what}: URI '{shown}' uses the scheme '{scheme}:'; only data: URIs and relative files \
             inside the asset's folder are allowed"
        )));
    }
    let decoded = percent_decode(uri.as_bytes())
        .ok_or_else(|| Error::invalid(format!("{what}: URI '{shown}' has a bad %-escape")))?;
    let decoded = String::from_utf8(decoded)
        .map_err(|_| Error::invalid(format!("{what}: URI '{shown}' is not UTF-8 once decoded")))?;
    let relative = relative_inside(&decoded).ok_or_else(|| {
        Error::invalid(format!(
            "{what}: URI '{shown}' is absolute or escapes the asset's folder; only relative \
             paths inside it are allowed"
        ))
    })?;
    let Some(base) = base else {
        return Err(Error::invalid(format!(
            "{what}: URI '{shown}' names an external file, but the asset was given as bytes with \
             no folder; embed the data (GLB or data: URIs) or load from a path"
        )));
    };
    Ok(UriTarget::File(base.join(relative)))
}

/// Reads a file that [`resolve`] accepted, refusing it when a symbolic link leads out of `base`
/// and checking its size against the budget before reading.
pub(crate) fn read_file(
    path: &Path,
    base: &Path,
    what: &str,
    budget: &mut MemoryBudget,
) -> Result<Vec<u8>> {
    let real = path.canonicalize().map_err(|e| Error::io(path, e))?;
    let real_base = base.canonicalize().map_err(|e| Error::io(base, e))?;
    if !real.starts_with(&real_base) {
        return Err(Error::invalid(format!(
            "{what}: '{}' resolves to '{}', outside the asset's folder '{}'",
            path.display(),
            real.display(),
            real_base.display()
        )));
    }
    let meta = std::fs::metadata(&real).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::invalid(format!(
            "{what}: '{}' is not a regular file",
            path.display()
        )));
    }
    budget.reserve(&format!("{what} ('{}')", path.display()), meta.len())?;
    std::fs::read(&real).map_err(|e| Error::io(path, e))
}

/// A URI cut to a printable length for messages (data: URIs can be megabytes).
fn shorten(uri: &str) -> String {
    const MAX: usize = 80;
    if uri.len() <= MAX {
        return uri.to_string();
    }
    let mut end = MAX;
    while !uri.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}…", &uri[..end])
}

/// The scheme of `uri` when it has one (RFC 3986: a letter, then letters, digits, `+`, `-`, `.`,
/// then `:`). A single letter is a Windows drive and is reported as a scheme too: it is absolute.
fn scheme_of(uri: &str) -> Option<&str> {
    let colon = uri.find(':')?;
    let scheme = &uri[..colon];
    let mut chars = scheme.chars();
    let first = chars.next()?;
    if first.is_ascii_alphabetic()
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
    {
        Some(scheme)
    } else {
        None
    }
}

/// The normalised relative path of `path`, or `None` when it is absolute, contains a NUL, or
/// climbs out of its root with `..`.
fn relative_inside(path: &str) -> Option<PathBuf> {
    if path.is_empty() || path.contains('\0') || path.starts_with('/') || path.starts_with('\\') {
        return None;
    }
    let mut parts: Vec<&str> = Vec::new();
    for part in path.split(['/', '\\']) {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop()?;
            }
            p => parts.push(p),
        }
    }
    if parts.is_empty() {
        return None;
    }
    Some(parts.iter().collect())
}

/// `data:[<media type>][;base64],<data>` after the `data:` prefix.
fn decode_data_uri(
    rest: &str,
    what: &str,
    shown: &str,
    budget: &mut MemoryBudget,
) -> Result<Vec<u8>> {
    let (header, payload) = rest.split_once(',').ok_or_else(|| {
        Error::format(format!(
            "{what}: data URI '{shown}' has no ',' before its data"
        ))
    })?;
    // Decoded data is never longer than its encoding.
    budget.reserve(&format!("{what} (data URI)"), payload.len() as u64)?;
    if header.ends_with(";base64") {
        base64_decode(payload.as_bytes()).map_err(|at| {
            Error::format(format!(
                "{what}: data URI '{shown}' has invalid base64 at character {at}"
            ))
        })
    } else {
        percent_decode(payload.as_bytes())
            .ok_or_else(|| Error::format(format!("{what}: data URI '{shown}' has a bad %-escape")))
    }
}

/// Standard base64 (RFC 4648, `+/`, optional `=` padding; whitespace is not allowed in a URI).
/// On failure returns the offset of the first bad character.
pub(crate) fn base64_decode(input: &[u8]) -> std::result::Result<Vec<u8>, usize> {
    fn value(c: u8) -> Option<u32> {
        match c {
            b'A'..=b'Z' => Some((c - b'A') as u32),
            b'a'..=b'z' => Some((c - b'a') as u32 + 26),
            b'0'..=b'9' => Some((c - b'0') as u32 + 52),
            b'+' | b'-' => Some(62),
            b'/' | b'_' => Some(63),
            _ => None,
        }
    }
    let trimmed_len = input.len()
        - input
            .iter()
            .rev()
            .take(2)
            .take_while(|&&c| c == b'=')
            .count();
    let data = &input[..trimmed_len];
    if data.len() % 4 == 1 {
        return Err(data.len().saturating_sub(1));
    }
    let mut out = Vec::with_capacity(data.len() / 4 * 3 + 2);
    for (chunk_index, chunk) in data.chunks(4).enumerate() {
        let mut acc = 0u32;
        for (i, &c) in chunk.iter().enumerate() {
            acc |= value(c).ok_or(chunk_index * 4 + i)? << (18 - 6 * i);
        }
        let bytes = acc.to_be_bytes();
        out.extend_from_slice(&bytes[1..chunk.len()]);
    }
    Ok(out)
}

/// `%XX` escapes decoded; `None` for a truncated or non-hex escape.
fn percent_decode(input: &[u8]) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(input.len());
    let mut i = 0;
    while i < input.len() {
        if input[i] == b'%' {
            let hex = input.get(i + 1..i + 3)?;
            let s = std::str::from_utf8(hex).ok()?;
            out.push(u8::from_str_radix(s, 16).ok()?);
            i += 3;
        } else {
            out.push(input[i]);
            i += 1;
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::super::limits::LoadLimits;
    use super::*;

    fn budget() -> MemoryBudget {
        MemoryBudget::new(&LoadLimits::default())
    }

    fn refused(uri: &str) -> String {
        let e = resolve(
            uri,
            Some(Path::new("/assets/car")),
            "buffer 0",
            &mut budget(),
        )
        .expect_err(uri);
        assert!(matches!(e, Error::InvalidArgument(_)), "{uri}: {e}");
        e.to_string()
    }

    #[test]
    fn base64_matches_rfc4648_vectors() {
        let cases = [
            ("", ""),
            ("Zg==", "f"),
            ("Zm8=", "fo"),
            ("Zm9v", "foo"),
            ("Zm9vYg==", "foob"),
            ("Zm9vYmE=", "fooba"),
            ("Zm9vYmFy", "foobar"),
            ("Zm9vYmE", "fooba"),
        ];
        for (enc, dec) in cases {
            assert_eq!(
                base64_decode(enc.as_bytes()).unwrap(),
                dec.as_bytes(),
                "{enc}"
            );
        }
        assert_eq!(base64_decode(b"Zm9v!mFy"), Err(4));
        assert!(base64_decode(b"Zm9vY").is_err());
    }

    #[test]
    fn data_uris_decode() {
        let t = resolve(
            "data:application/octet-stream;base64,AAEC",
            None,
            "b",
            &mut budget(),
        )
        .unwrap();
        assert_eq!(t, UriTarget::Data(vec![0, 1, 2]));
        let t = resolve("data:,a%20b", None, "b", &mut budget()).unwrap();
        assert_eq!(t, UriTarget::Data(b"a b".to_vec()));
        let e = resolve("data:;base64,AA*A", None, "buffer 2", &mut budget()).unwrap_err();
        assert!(e.to_string().contains("buffer 2"), "{e}");
        assert!(resolve("data:nocomma", None, "b", &mut budget()).is_err());
    }

    #[test]
    fn relative_files_inside_the_folder_resolve() {
        let base = Path::new("/assets/car");
        let ok = |uri: &str| match resolve(uri, Some(base), "b", &mut budget()).unwrap() {
            UriTarget::File(p) => p,
            other => panic!("{other:?}"),
        };
        assert_eq!(ok("mesh.bin"), base.join("mesh.bin"));
        assert_eq!(ok("tex/a%20b.png"), base.join("tex").join("a b.png"));
        assert_eq!(ok("./tex/../mesh.bin"), base.join("mesh.bin"));
    }

    #[test]
    fn escaping_absolute_and_network_uris_are_refused_by_name() {
        for uri in [
            "../secret.bin",
            "tex/../../secret.bin",
            "%2E%2E/secret.bin",
            "/etc/passwd",
            "\\\\server\\share\\x.bin",
            "C:/Windows/x.bin",
            "c:\\x.bin",
            "http://example.com/x.bin",
            "https://example.com/x.bin",
            "file:///etc/passwd",
            "ftp://h/x",
            "",
            ".",
            "a%00b",
        ] {
            let msg = refused(uri);
            assert!(msg.contains("buffer 0"), "{msg}");
        }
        assert!(refused("http://example.com/x.bin").contains("http:"));
    }

    #[test]
    fn external_files_need_a_base_folder() {
        let e = resolve("mesh.bin", None, "image 1", &mut budget()).unwrap_err();
        assert!(matches!(e, Error::InvalidArgument(_)));
        assert!(e.to_string().contains("mesh.bin"), "{e}");
    }

    #[test]
    fn data_uri_over_the_budget_is_refused_before_decoding() {
        let mut b = MemoryBudget::new(&LoadLimits {
            max_total_bytes: 10,
            ..LoadLimits::default()
        });
        let e = resolve("data:;base64,AAAAAAAAAAAAAAAA", None, "b", &mut b).unwrap_err();
        assert!(matches!(e, Error::TooLarge(_)), "{e}");
    }

    #[test]
    fn symlinks_out_of_the_folder_are_refused() {
        let outer = tempfile::tempdir().unwrap();
        let base = outer.path().join("asset");
        std::fs::create_dir(&base).unwrap();
        std::fs::write(outer.path().join("secret.bin"), b"secret").unwrap();
        std::fs::write(base.join("ok.bin"), b"ok").unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(outer.path().join("secret.bin"), base.join("link.bin")).unwrap();
        assert_eq!(
            read_file(&base.join("ok.bin"), &base, "b", &mut budget()).unwrap(),
            b"ok"
        );
        #[cfg(unix)]
        {
            let e =
                read_file(&base.join("link.bin"), &base, "buffer 0", &mut budget()).unwrap_err();
            assert!(matches!(e, Error::InvalidArgument(_)), "{e}");
        }
        let e = read_file(&base.join("missing.bin"), &base, "b", &mut budget()).unwrap_err();
        assert!(matches!(e, Error::Io { .. }), "{e}");
    }
}
