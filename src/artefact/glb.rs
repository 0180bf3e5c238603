//! The GLB container (glTF 2.0 spec §4.4): a 12-byte header, a JSON chunk, an optional BIN
//! chunk. Parsed here with every length checked, rather than by the `gltf` crate, whose parser
//! subtracts the header size from the declared length unchecked.

use crate::error::{Error, Result};

const MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// The chunks of a GLB file, borrowed from its bytes.
#[derive(Debug)]
pub(crate) struct Glb<'a> {
    pub(crate) json: &'a [u8],
    pub(crate) bin: Option<&'a [u8]>,
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// `true` when `bytes` start like a GLB file.
pub(crate) fn is_glb(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Splits a GLB file into its JSON and BIN chunks.
///
/// # Errors
/// `Format` naming the field for a wrong version, a declared length past the data, a missing or
/// misplaced JSON chunk, or a chunk running past the file. Unknown chunk types are skipped (the
/// spec asks readers to ignore them).
pub(crate) fn parse(bytes: &[u8]) -> Result<Glb<'_>> {
    let bad = |m: String| Error::format(format!("invalid GLB: {m}"));
    let version = u32_at(bytes, 4).ok_or_else(|| bad("file shorter than its header".into()))?;
    if version != 2 {
        return Err(bad(format!(
            "container version {version}; only 2 is supported"
        )));
    }
    let length = u32_at(bytes, 8).ok_or_else(|| bad("file shorter than its header".into()))?;
    let length = length as usize;
    if length > bytes.len() || length < 12 {
        return Err(bad(format!(
            "header declares {length} bytes but the data holds {}",
            bytes.len()
        )));
    }
    let data = &bytes[..length];
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    let mut index = 0;
    while at < data.len() {
        let chunk_len = u32_at(data, at)
            .ok_or_else(|| bad(format!("chunk {index} header is truncated")))?
            as usize;
        let kind = u32_at(data, at + 4)
            .ok_or_else(|| bad(format!("chunk {index} header is truncated")))?;
        let start = at + 8;
        let end = start
            .checked_add(chunk_len)
            .filter(|&e| e <= data.len())
            .ok_or_else(|| {
                bad(format!(
                    "chunk {index} declares {chunk_len} bytes, past the end of the file"
                ))
            })?;
        let body = &data[start..end];
        match (index, kind) {
            (0, CHUNK_JSON) => json = Some(body),
            (0, _) => return Err(bad("the first chunk is not JSON".into())),
            (_, CHUNK_JSON) => return Err(bad(format!("chunk {index} is a second JSON chunk"))),
            (1, CHUNK_BIN) => bin = Some(body),
            (_, CHUNK_BIN) => return Err(bad(format!("chunk {index} is a misplaced BIN chunk"))),
            _ => {}
        }
        at = end;
        index += 1;
    }
    let json = json.ok_or_else(|| bad("no JSON chunk".into()))?;
    Ok(Glb { json, bin })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn glb(chunks: &[(u32, &[u8])]) -> Vec<u8> {
        let mut out = b"glTF".to_vec();
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        for (kind, body) in chunks {
            out.extend_from_slice(&(body.len() as u32).to_le_bytes());
            out.extend_from_slice(&kind.to_le_bytes());
            out.extend_from_slice(body);
        }
        let n = out.len() as u32;
        out[8..12].copy_from_slice(&n.to_le_bytes());
        out
    }

    #[test]
    fn splits_json_and_bin() {
        let bytes = glb(&[(CHUNK_JSON, b"{}  "), (CHUNK_BIN, &[1, 2, 3, 4])]);
        let g = parse(&bytes).unwrap();
        assert_eq!(g.json, b"{}  ");
        assert_eq!(g.bin, Some(&[1u8, 2, 3, 4][..]));
        let only_json = glb(&[(CHUNK_JSON, b"{}  ")]);
        assert!(parse(&only_json).unwrap().bin.is_none());
    }

    #[test]
    fn rejects_bad_lengths_versions_and_orders() {
        let good = glb(&[(CHUNK_JSON, b"{}  "), (CHUNK_BIN, &[1, 2, 3, 4])]);
        for cut in 0..good.len() {
            // Every truncation either fails cleanly or (when the header length is patched) parses.
            let _ = parse(&good[..cut]);
        }
        let mut v1 = good.clone();
        v1[4] = 1;
        assert!(parse(&v1).unwrap_err().to_string().contains("version 1"));
        let mut short = good.clone();
        short[8..12].copy_from_slice(&5u32.to_le_bytes());
        assert!(parse(&short).is_err());
        let mut huge_chunk = good.clone();
        huge_chunk[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(parse(&huge_chunk)
            .unwrap_err()
            .to_string()
            .contains("chunk 0"));
        assert!(parse(&glb(&[(CHUNK_BIN, &[0; 4])])).is_err());
        assert!(parse(&glb(&[(CHUNK_JSON, b"{}  "), (CHUNK_JSON, b"{}  ")])).is_err());
        assert!(parse(&glb(&[])).is_err());
    }
}
