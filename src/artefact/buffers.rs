//! Buffers, buffer views and accessors, read with every offset, length, stride and type checked
//! against the bytes that are really there.

use std::path::Path;

use gltf::accessor::{DataType, Dimensions};

use super::limits::{mul, MemoryBudget};
use super::uri::{self, UriTarget};
use crate::error::{Error, Result};

/// The bytes of every buffer of an asset, each exactly its declared `byteLength` long.
pub(crate) struct Buffers {
    data: Vec<Vec<u8>>,
}

impl Buffers {
    /// Resolves every buffer: the GLB binary chunk, `data:` URIs, or files inside `base`.
    ///
    /// # Errors
    /// `Format` when a buffer holds fewer bytes than it declares or refers to a missing GLB
    /// chunk; the URI policy's errors; `Io` for a missing file.
    pub(crate) fn load(
        doc: &gltf::Document,
        mut blob: Option<Vec<u8>>,
        base: Option<&Path>,
        budget: &mut MemoryBudget,
    ) -> Result<Self> {
        let mut data = Vec::new();
        for buffer in doc.buffers() {
            let what = format!("buffer {}", buffer.index());
            let declared = buffer.length();
            let mut bytes = match buffer.source() {
                gltf::buffer::Source::Bin => {
                    let bin = blob.take().ok_or_else(|| {
                        Error::format(format!(
                            "{what} has no URI, so it must be the GLB binary chunk, but the file \
                             has none (or another buffer already used it)"
                        ))
                    })?;
                    budget.reserve(&format!("{what} (GLB binary chunk)"), bin.len() as u64)?;
                    bin
                }
                gltf::buffer::Source::Uri(u) => match uri::resolve(u, base, &what, budget)? {
                    UriTarget::Data(bytes) => bytes,
                    UriTarget::File(path) => {
                        // `resolve` only returns a file when there is a base folder.
                        let base = base.ok_or_else(|| {
                            Error::Internal(format!("{what}: file URI without a base folder"))
                        })?;
                        uri::read_file(&path, base, &what, budget)?
                    }
                },
            };
            if bytes.len() < declared {
                return Err(Error::format(format!(
                    "{what} declares byteLength {declared} but its data holds only {} bytes",
                    bytes.len()
                )));
            }
            // The GLB chunk may carry up to 3 bytes of padding; nothing may be read past byteLength.
            bytes.truncate(declared);
            data.push(bytes);
        }
        Ok(Buffers { data })
    }

    /// The bytes of buffer view `view`, checked against its buffer.
    pub(crate) fn view_bytes(&self, view: &gltf::buffer::View) -> Result<&[u8]> {
        let buffer = view.buffer().index();
        let bytes = self.data.get(buffer).ok_or_else(|| {
            Error::format(format!(
                "bufferView {} refers to buffer {buffer}, which does not exist",
                view.index()
            ))
        })?;
        let start = view.offset();
        let end = start.checked_add(view.length());
        match end {
            Some(end) if end <= bytes.len() => Ok(&bytes[start..end]),
            _ => Err(Error::format(format!(
                "bufferView {}: byteOffset {start} + byteLength {} is past the end of buffer \
                 {buffer} ({} bytes)",
                view.index(),
                view.length(),
                bytes.len()
            ))),
        }
    }
}

/// Bytes of one element's component type.
fn component_size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

fn dimension_count(d: Dimensions) -> usize {
    match d {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 => 4,
        Dimensions::Mat2 => 4,
        Dimensions::Mat3 => 9,
        Dimensions::Mat4 => 16,
    }
}

/// One component as f32 under the glTF rules for normalized integers (spec §3.11).
fn component(bytes: &[u8], t: DataType, normalized: bool) -> f32 {
    match (t, normalized) {
        (DataType::F32, _) => f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
        (DataType::U8, true) => bytes[0] as f32 / 255.0,
        (DataType::U8, false) => bytes[0] as f32,
        (DataType::I8, true) => (bytes[0] as i8 as f32 / 127.0).max(-1.0),
        (DataType::I8, false) => bytes[0] as i8 as f32,
        (DataType::U16, n) => {
            let v = u16::from_le_bytes([bytes[0], bytes[1]]) as f32;
            if n {
                v / 65535.0
            } else {
                v
            }
        }
        (DataType::I16, n) => {
            let v = i16::from_le_bytes([bytes[0], bytes[1]]) as f32;
            if n {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        (DataType::U32, n) => {
            let v = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f32;
            if n {
                v / 4294967295.0
            } else {
                v
            }
        }
    }
}

/// The validated layout of `count` elements in a slice of bytes.
struct Strided<'a> {
    bytes: &'a [u8],
    stride: usize,
    element: usize,
    count: usize,
}

impl Strided<'_> {
    fn element(&self, i: usize) -> &[u8] {
        &self.bytes[i * self.stride..i * self.stride + self.element]
    }
}

/// Checks that `count` elements of `element` bytes at `offset` in `view` (with its stride) fit.
fn strided<'a>(
    buffers: &'a Buffers,
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    element: usize,
    component: usize,
    what: &str,
) -> Result<Strided<'a>> {
    let bytes = buffers.view_bytes(view)?;
    let stride = match view.stride() {
        None => element,
        Some(s) => {
            if s < element || s % component != 0 {
                return Err(Error::format(format!(
                    "{what}: bufferView {} has byteStride {s}, which is smaller than one element \
                     ({element} bytes) or not a multiple of the component size {component}",
                    view.index()
                )));
            }
            s
        }
    };
    let too_far = || {
        Error::format(format!(
            "{what}: {count} elements of {element} bytes with stride {stride} from byteOffset \
             {offset} run past the end of bufferView {} ({} bytes)",
            view.index(),
            bytes.len()
        ))
    };
    if count == 0 {
        return Ok(Strided {
            bytes: &[],
            stride,
            element,
            count,
        });
    }
    let span = (count as u64 - 1)
        .checked_mul(stride as u64)
        .and_then(|s| s.checked_add(element as u64))
        .and_then(|s| s.checked_add(offset as u64))
        .ok_or_else(too_far)?;
    if span > bytes.len() as u64 {
        return Err(too_far());
    }
    Ok(Strided {
        bytes: &bytes[offset..span as usize],
        stride,
        element,
        count,
    })
}

/// Reads a float or normalized-integer accessor of one of the `allowed` shapes into a flat
/// `Vec<f32>` (`count × components`), with sparse substitution applied.
///
/// `max_count` is the most elements the caller accepts (checked before allocating, so that an
/// accessor with no bufferView that claims a huge count of zeros costs nothing).
///
/// # Errors
/// `Format` naming `what` and the accessor for a wrong shape, an out-of-bounds read, a bad
/// sparse block; `TooLarge` past `max_count` or the budget.
pub(crate) fn read_floats(
    accessor: &gltf::Accessor,
    buffers: &Buffers,
    allowed: &[Dimensions],
    max_count: u64,
    what: &str,
    budget: &mut MemoryBudget,
) -> Result<(Vec<f32>, usize)> {
    let what = format!("{what} (accessor {})", accessor.index());
    let dims = accessor.dimensions();
    if !allowed.contains(&dims) {
        return Err(Error::format(format!(
            "{what} has type {dims:?}; expected one of {allowed:?}"
        )));
    }
    let n = dimension_count(dims);
    let t = accessor.data_type();
    let normalized = accessor.normalized();
    let count = accessor.count();
    if count == 0 {
        return Err(Error::format(format!("{what} has count 0 (must be ≥ 1)")));
    }
    if count as u64 > max_count {
        return Err(Error::TooLarge(format!(
            "{what} has {count} elements, over the cap of {max_count}"
        )));
    }
    let bytes = mul(mul(count as u64, n as u64, &what)?, 4, &what)?;
    budget.reserve(&what, bytes)?;
    let csize = component_size(t);
    let mut out = vec![0f32; count * n];
    if let Some(view) = accessor.view() {
        let s = strided(
            buffers,
            &view,
            accessor.offset(),
            count,
            n * csize,
            csize,
            &what,
        )?;
        for i in 0..s.count {
            let e = s.element(i);
            for c in 0..n {
                out[i * n + c] = component(&e[c * csize..], t, normalized);
            }
        }
    }
    if let Some(sparse) = accessor.sparse() {
        let targets = read_sparse_indices(&sparse, buffers, count, &what)?;
        let values = sparse.values();
        let s = strided(
            buffers,
            &values.view(),
            values.offset(),
            targets.len(),
            n * csize,
            csize,
            &format!("{what} sparse values"),
        )?;
        for (k, &target) in targets.iter().enumerate() {
            let e = s.element(k);
            for c in 0..n {
                out[target as usize * n + c] = component(&e[c * csize..], t, normalized);
            }
        }
    }
    Ok((out, n))
}

/// The element indices a sparse block overrides, each checked against the accessor's count.
fn read_sparse_indices(
    sparse: &gltf::accessor::sparse::Sparse,
    buffers: &Buffers,
    count: usize,
    what: &str,
) -> Result<Vec<u32>> {
    use gltf::accessor::sparse::IndexType;
    let n = sparse.count();
    if n > count {
        return Err(Error::format(format!(
            "{what}: sparse count {n} is larger than the accessor's count {count}"
        )));
    }
    let indices = sparse.indices();
    let (t, size) = match indices.index_type() {
        IndexType::U8 => (DataType::U8, 1),
        IndexType::U16 => (DataType::U16, 2),
        IndexType::U32 => (DataType::U32, 4),
    };
    let s = strided(
        buffers,
        &indices.view(),
        indices.offset(),
        n,
        size,
        size,
        &format!("{what} sparse indices"),
    )?;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let i = index_value(s.element(k), t);
        if i as usize >= count {
            return Err(Error::format(format!(
                "{what}: sparse index {k} is {i}, out of range for {count} elements"
            )));
        }
        out.push(i);
    }
    Ok(out)
}

fn index_value(bytes: &[u8], t: DataType) -> u32 {
    match t {
        DataType::U8 => bytes[0] as u32,
        DataType::U16 => u16::from_le_bytes([bytes[0], bytes[1]]) as u32,
        _ => u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
    }
}

/// Reads an index accessor (unsigned 8/16/32-bit scalars) and checks every index against
/// `vertex_count`.
///
/// # Errors
/// `Format` naming `what`, the accessor, the position and the value of the first bad index, or a
/// wrong component type; `TooLarge` past `max_count` or the budget.
pub(crate) fn read_indices(
    accessor: &gltf::Accessor,
    buffers: &Buffers,
    vertex_count: usize,
    max_count: u64,
    what: &str,
    budget: &mut MemoryBudget,
) -> Result<Vec<u32>> {
    let what = format!("{what} indices (accessor {})", accessor.index());
    let t = accessor.data_type();
    if accessor.dimensions() != Dimensions::Scalar
        || !matches!(t, DataType::U8 | DataType::U16 | DataType::U32)
        || accessor.normalized()
    {
        return Err(Error::format(format!(
            "{what} is {:?} {t:?}{}; indices must be unsigned 8-, 16- or 32-bit scalars",
            accessor.dimensions(),
            if accessor.normalized() {
                " normalized"
            } else {
                ""
            }
        )));
    }
    let count = accessor.count();
    if count as u64 > max_count {
        return Err(Error::TooLarge(format!(
            "{what} has {count} indices, over the cap of {max_count}"
        )));
    }
    budget.reserve(&what, mul(count as u64, 4, &what)?)?;
    let mut out = vec![0u32; count];
    if let Some(view) = accessor.view() {
        let size = component_size(t);
        let s = strided(buffers, &view, accessor.offset(), count, size, size, &what)?;
        for (i, o) in out.iter_mut().enumerate() {
            *o = index_value(s.element(i), t);
        }
    }
    if let Some(sparse) = accessor.sparse() {
        let targets = read_sparse_indices(&sparse, buffers, count, &what)?;
        let values = sparse.values();
        let size = component_size(t);
        let s = strided(
            buffers,
            &values.view(),
            values.offset(),
            targets.len(),
            size,
            size,
            &format!("{what} sparse values"),
        )?;
        for (k, &target) in targets.iter().enumerate() {
            out[target as usize] = index_value(s.element(k), t);
        }
    }
    if let Some((position, &value)) = out
        .iter()
        .enumerate()
        .find(|(_, &v)| v as usize >= vertex_count)
    {
        return Err(Error::format(format!(
            "{what}: index {position} is {value}, out of range for {vertex_count} vertices"
        )));
    }
    Ok(out)
}
