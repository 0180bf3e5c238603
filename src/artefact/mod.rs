//! Artefacts: the glTF 2.0 objects inserted into the photo (thesis §3.2.2.1, Appendix C.1).
//!
//! [`Artefact::from_path`] / [`Artefact::from_glb_bytes`] load `.gltf` (external or embedded
//! buffers) and `.glb` files without trusting them: every accessor is checked against its buffer,
//! every index against the vertex count, the node graph for cycles, every URI against a policy
//! (see [`uri`](self) docs: `data:` or files inside the asset's folder only), and the counts the
//! file claims against [`LoadLimits`] before anything of that size is allocated.
//!
//! The loaded [`Artefact`] holds triangle lists whose vertices are already transformed by the
//! node hierarchy ("asset space": the glTF scene's root space, metres, +Y up), complete normals
//! (and tangents where a normal map needs them), the [`Material`]s and shared decoded textures,
//! and the warnings about everything that was repaired or ignored. An [`ArtefactSet`] places
//! several artefacts in a scene, sharing the data of an asset placed many times.

mod attributes;
mod buffers;
pub mod builtin;
mod extensions;
mod glb;
mod instances;
mod limits;
mod load;
mod material;
mod mesh;
mod uri;

use std::path::Path;

use glam::{Mat4, Vec2, Vec3, Vec4};

pub use builtin::{builtin_glb, BUILTIN_ARTEFACTS};
pub use extensions::SUPPORTED_EXTENSIONS;
pub use instances::{ArtefactId, ArtefactSet, Instance};
pub use limits::LoadLimits;
pub use material::{
    AlphaMode, Filter, Material, Sampler, Texture, TextureImage, TextureRef, UvTransform, Wrap,
};

use crate::error::{Error, Result};

/// Options for loading an artefact.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// Caps on vertices, triangles, texture size, memory and nodes.
    pub limits: LoadLimits,
}

/// An axis-aligned bounding box, in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Aabb {
    /// The degenerate box at the origin (the bounds of an artefact with no geometry).
    pub const ZERO: Aabb = Aabb {
        min: Vec3::ZERO,
        max: Vec3::ZERO,
    };

    /// The smallest box holding `points`, or `None` when there are none.
    pub fn from_points(points: &[Vec3]) -> Option<Aabb> {
        let first = *points.first()?;
        let mut b = Aabb {
            min: first,
            max: first,
        };
        for &p in points {
            b.min = b.min.min(p);
            b.max = b.max.max(p);
        }
        Some(b)
    }

    /// The smallest box holding both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// The box holding this one after `transform` (its eight corners transformed).
    pub fn transformed(&self, transform: &Mat4) -> Aabb {
        let corners: Vec<Vec3> = (0..8)
            .map(|i| {
                let c = Vec3::new(
                    if i & 1 == 0 { self.min.x } else { self.max.x },
                    if i & 2 == 0 { self.min.y } else { self.max.y },
                    if i & 4 == 0 { self.min.z } else { self.max.z },
                );
                transform.transform_point3(c)
            })
            .collect();
        // Eight points are never empty.
        Aabb::from_points(&corners).unwrap_or(*self)
    }

    /// Centre point.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Extent along each axis.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }
}

/// One drawable piece: a mesh primitive of one node, as an indexed triangle list in asset space.
///
/// All vertex arrays have the same length; `indices` holds 3 entries per triangle, each less
/// than that length, counter-clockwise front faces (glTF convention; mirroring node transforms
/// already compensated).
#[derive(Debug, Clone)]
pub struct Primitive {
    /// glTF mesh index.
    pub mesh: usize,
    /// glTF mesh name.
    pub mesh_name: Option<String>,
    /// glTF node index whose transform was applied.
    pub node: usize,
    /// Index of the primitive within its mesh.
    pub primitive: usize,
    /// Positions in asset space, metres.
    pub positions: Vec<Vec3>,
    /// Unit normals in asset space (generated when missing or unusable; see the warnings).
    pub normals: Vec<Vec3>,
    /// Unit tangents (xyz) with bitangent sign (w = ±1); present when the material has a normal map.
    pub tangents: Option<Vec<Vec4>>,
    /// `TEXCOORD_0`.
    pub uv0: Option<Vec<Vec2>>,
    /// `TEXCOORD_1`.
    pub uv1: Option<Vec<Vec2>>,
    /// `COLOR_0`, linear RGBA in [0, 1] (alpha 1 when the file gives RGB).
    pub colors: Option<Vec<Vec4>>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// Index into [`Artefact::materials`].
    pub material: usize,
    /// Bounds of `positions`.
    pub bounds: Aabb,
}

impl Primitive {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A loaded glTF asset, flattened and validated. See the module documentation.
#[derive(Debug, Clone)]
pub struct Artefact {
    /// Where it came from (a path, or `"memory"`).
    pub source: String,
    /// Drawable primitives, one per (node, mesh primitive) pair.
    pub primitives: Vec<Primitive>,
    /// Materials referred to by [`Primitive::material`].
    pub materials: Vec<Material>,
    /// Textures referred to by [`TextureRef::texture`].
    pub textures: Vec<Texture>,
    /// `extensionsUsed` of the file.
    pub extensions_used: Vec<String>,
    /// `extensionsRequired` of the file.
    pub extensions_required: Vec<String>,
    /// What was repaired or ignored while loading (each names the node, mesh, accessor, …).
    pub warnings: Vec<String>,
    /// Bounds of all primitives in asset space ([`Aabb::ZERO`] when there is no geometry).
    pub bounds: Aabb,
}

impl Artefact {
    /// Loads a `.gltf` or `.glb` file. External buffers and images are read only from the
    /// file's folder (and below).
    ///
    /// # Errors
    /// `Io` when the file (or a buffer or image it names) cannot be read; `Format` for malformed
    /// data (the message names the accessor, index, node or URI); `Unsupported` for a required
    /// extension this loader lacks; `TooLarge` past `options.limits`; `InvalidArgument` for a
    /// refused URI.
    pub fn from_path(path: impl AsRef<Path>, options: &LoadOptions) -> Result<Artefact> {
        let path = path.as_ref();
        let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
        if meta.len() > options.limits.max_total_bytes {
            return Err(Error::TooLarge(format!(
                "{} is {} bytes, over the cap of {} bytes (LoadLimits::max_total_bytes)",
                path.display(),
                meta.len(),
                options.limits.max_total_bytes
            )));
        }
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let base = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        };
        load::load(&bytes, Some(&base), &path.display().to_string(), options)
    }

    /// Loads a GLB, or `.gltf` JSON whose buffers and images are all embedded as `data:` URIs,
    /// from memory. A URI naming an external file is refused (`InvalidArgument`): there is no
    /// folder to resolve it in; use [`Artefact::from_bytes_in`] for that.
    ///
    /// # Errors
    /// As [`Artefact::from_path`].
    pub fn from_glb_bytes(bytes: &[u8], options: &LoadOptions) -> Result<Artefact> {
        load::load(bytes, None, "memory", options)
    }

    /// Loads `.gltf` or `.glb` bytes whose external files, if any, live in `folder`.
    ///
    /// # Errors
    /// As [`Artefact::from_path`].
    pub fn from_bytes_in(
        bytes: &[u8],
        folder: impl AsRef<Path>,
        options: &LoadOptions,
    ) -> Result<Artefact> {
        load::load(bytes, Some(folder.as_ref()), "memory", options)
    }

    /// Total triangles over all primitives.
    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(Primitive::triangle_count).sum()
    }

    /// Total vertices over all primitives.
    pub fn vertex_count(&self) -> usize {
        self.primitives.iter().map(|p| p.positions.len()).sum()
    }

    /// `true` when there is nothing to draw.
    pub fn is_empty(&self) -> bool {
        self.triangle_count() == 0
    }
}
