//! The artefacts of a [`Scene`] (issue 7): glTF objects placed in the photo, each with its own
//! transform, visibility and shadow flags.
//!
//! Artefacts are a scene input of their own, with their own version: adding, moving or removing
//! one changes nothing the reconstruction products (stereo, depth, mesh, surfaces) depend on, so
//! those are reused. Products that draw the artefacts key on [`Scene::artefacts_version`].
//!
//! A file added twice (same canonical path, same size and modification time) is loaded once and
//! shared: every instance holds the same `Arc<Artefact>`, so its data (and later its GPU buffers)
//! exists once however many times it is placed.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Weak};
use std::time::SystemTime;

use glam::{Mat4, Vec2};

use super::Scene;
use crate::artefact::{Aabb, Artefact, ArtefactId, ArtefactSet, LoadLimits, LoadOptions};
use crate::error::{Error, Result};
use crate::mesh::{PlaceOptions, Placement};
use crate::trace::StageStatus;

/// What identifies one version of a file on disk: a changed file is loaded again.
#[derive(Debug, Clone, PartialEq, Eq)]
struct FileStamp {
    len: u64,
    modified: Option<SystemTime>,
}

/// The scene's artefact input and the cache of loaded files.
#[derive(Debug, Default, Clone)]
pub(super) struct SceneArtefacts {
    set: ArtefactSet,
    version: u64,
    limits: LoadLimits,
    /// Loaded files by canonical path. Weak, so removing the last instance frees the data.
    loaded: HashMap<PathBuf, (FileStamp, Weak<Artefact>)>,
}

/// An artefact's bounding boxes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArtefactBounds {
    /// In the artefact's own (asset) space, metres.
    pub local: Aabb,
    /// In the world (camera) frame after its transform, metres.
    pub world: Aabb,
}

impl Scene {
    fn artefacts_changed(&mut self) {
        self.artefacts.version = self.bump();
    }

    /// The version of the artefact input: it changes whenever an artefact is added, moved,
    /// shown, hidden, has its shadow flags changed or is removed.
    pub fn artefacts_version(&self) -> u64 {
        self.artefacts.version
    }

    /// Sets the caps used by [`Scene::add_artefact_path`] and [`Scene::add_artefact_bytes`]
    /// (the [`LoadLimits`] defaults until then). Artefacts already added are kept.
    pub fn set_artefact_limits(&mut self, limits: LoadLimits) {
        self.artefacts.limits = limits;
    }

    /// The caps artefacts are loaded with.
    pub fn artefact_limits(&self) -> LoadLimits {
        self.artefacts.limits
    }

    /// Places an already loaded artefact with `transform` (asset space → world, metres): visible,
    /// casting and receiving shadows. Adding the same `Arc` several times shares its data.
    ///
    /// # Errors
    /// `InvalidArgument` for a non-finite transform; the scene is unchanged.
    pub fn add_artefact(&mut self, artefact: Arc<Artefact>, transform: Mat4) -> Result<ArtefactId> {
        let id = self.artefacts.set.add(artefact, transform)?;
        self.artefacts_changed();
        Ok(id)
    }

    /// Loads a `.gltf` or `.glb` file (with [`Scene::artefact_limits`]) and places it with
    /// `transform`. A file already loaded by this scene and unchanged on disk is not read again:
    /// the new instance shares its data. The call's trace ([`Scene::last_trace`]) has a stage
    /// `artefact.load` (computed, or reused when shared) and the loader's warnings.
    ///
    /// # Errors
    /// As [`Artefact::from_path`]; `InvalidArgument` for a non-finite transform. On error the
    /// scene is unchanged.
    pub fn add_artefact_path(
        &mut self,
        path: impl AsRef<Path>,
        transform: Mat4,
    ) -> Result<ArtefactId> {
        let path = path.as_ref();
        check_transform(&transform)?;
        self.traced(|scene, trace| {
            let canonical = std::fs::canonicalize(path).map_err(|e| Error::io(path, e))?;
            let meta = std::fs::metadata(&canonical).map_err(|e| Error::io(path, e))?;
            let stamp = FileStamp {
                len: meta.len(),
                modified: meta.modified().ok(),
            };
            let cached = scene
                .artefacts
                .loaded
                .get(&canonical)
                .filter(|(s, _)| *s == stamp)
                .and_then(|(_, weak)| weak.upgrade());
            let artefact = match cached {
                Some(a) => {
                    trace.record(
                        "artefact.load",
                        StageStatus::Reused,
                        0.0,
                        format!("{} is already loaded: shared", path.display()),
                    );
                    a
                }
                None => {
                    let options = LoadOptions {
                        limits: scene.artefacts.limits,
                    };
                    let loaded = trace.time("artefact.load", "first load of this file", |_| {
                        Artefact::from_path(path, &options)
                    })?;
                    let a = Arc::new(loaded);
                    scene
                        .artefacts
                        .loaded
                        .retain(|_, (_, weak)| weak.strong_count() > 0);
                    scene
                        .artefacts
                        .loaded
                        .insert(canonical, (stamp, Arc::downgrade(&a)));
                    a
                }
            };
            for w in &artefact.warnings {
                trace.warn(format!("{}: {w}", path.display()));
            }
            scene.add_artefact(artefact, transform)
        })
    }

    /// Loads a GLB (or `.gltf` with only embedded `data:` buffers and images) from memory, with
    /// [`Scene::artefact_limits`], and places it with `transform`. The trace has a stage
    /// `artefact.load` and the loader's warnings.
    ///
    /// # Errors
    /// As [`Artefact::from_glb_bytes`]; `InvalidArgument` for a non-finite transform. On error
    /// the scene is unchanged.
    pub fn add_artefact_bytes(&mut self, bytes: &[u8], transform: Mat4) -> Result<ArtefactId> {
        check_transform(&transform)?;
        self.traced(|scene, trace| {
            let options = LoadOptions {
                limits: scene.artefacts.limits,
            };
            let artefact = trace.time("artefact.load", "from memory", |_| {
                Artefact::from_glb_bytes(bytes, &options)
            })?;
            for w in &artefact.warnings {
                trace.warn(format!("memory: {w}"));
            }
            scene.add_artefact(Arc::new(artefact), transform)
        })
    }

    /// Moves an artefact (asset space → world, metres). Reconstruction products are not affected.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown id or a non-finite transform; the scene is unchanged.
    pub fn set_artefact_transform(&mut self, id: ArtefactId, transform: Mat4) -> Result<()> {
        self.artefacts.set.set_transform(id, transform)?;
        self.artefacts_changed();
        Ok(())
    }

    /// Shows or hides an artefact.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown id.
    pub fn set_artefact_visible(&mut self, id: ArtefactId, visible: bool) -> Result<()> {
        self.artefacts.set.set_visible(id, visible)?;
        self.artefacts_changed();
        Ok(())
    }

    /// Sets whether an artefact casts shadows (onto the photo and other artefacts) and receives
    /// them (from other artefacts).
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown id.
    pub fn set_artefact_shadows(
        &mut self,
        id: ArtefactId,
        casts_shadow: bool,
        receives_shadow: bool,
    ) -> Result<()> {
        self.artefacts
            .set
            .set_shadows(id, casts_shadow, receives_shadow)?;
        self.artefacts_changed();
        Ok(())
    }

    /// Removes an artefact. Its id is never given out again.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown or already removed id.
    pub fn remove_artefact(&mut self, id: ArtefactId) -> Result<()> {
        self.artefacts.set.remove(id)?;
        self.artefacts_changed();
        Ok(())
    }

    /// The scene's artefacts (read access: iterate, get by id, world bounds of all).
    pub fn artefacts(&self) -> &ArtefactSet {
        &self.artefacts.set
    }

    /// Local (asset space) and world bounding boxes of an artefact, metres.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown id.
    pub fn artefact_bounds(&self, id: ArtefactId) -> Result<ArtefactBounds> {
        let instance = self.artefact_instance(id)?;
        Ok(ArtefactBounds {
            local: instance.local_bounds(),
            world: instance.world_bounds(),
        })
    }

    fn artefact_instance(&self, id: ArtefactId) -> Result<&crate::artefact::Instance> {
        self.artefacts
            .set
            .get(id)
            .ok_or_else(|| Error::invalid(format!("no artefact with id {}", id.0)))
    }

    /// Stands an artefact on the scene surface seen at `pixel` ([`Scene::place`]) at its real
    /// size: its bounding box's bottom centre on the surface, its largest side `size_m` metres,
    /// turned by `yaw_rad` about the up axis. Sets its transform and returns the placement. The
    /// lighting estimate is built around [`Scene::set_insertion_point`], not around the
    /// artefacts: name the placed object's position there so that it is lit from where it stands.
    ///
    /// # Errors
    /// `InvalidArgument` for an unknown id, an artefact without geometry (empty bounds), and as
    /// [`Scene::place`]. On error the artefact keeps its transform.
    pub fn place_artefact(
        &mut self,
        id: ArtefactId,
        pixel: Vec2,
        size_m: f32,
        yaw_rad: f32,
    ) -> Result<Placement> {
        let local = self.artefact_instance(id)?.local_bounds();
        if local.size().max_element() <= 0.0 {
            return Err(Error::invalid(format!(
                "artefact {} has no extent (no geometry): it cannot be placed by size",
                id.0
            )));
        }
        let options = PlaceOptions {
            model_bounds: Some([local.min, local.max]),
            ..PlaceOptions::default()
        };
        let placement = self.place(pixel, size_m, yaw_rad, &options)?;
        self.set_artefact_transform(id, placement.transform)?;
        Ok(placement)
    }
}

fn check_transform(transform: &Mat4) -> Result<()> {
    if transform.is_finite() {
        Ok(())
    } else {
        Err(Error::invalid(format!(
            "artefact transform has a non-finite element: {transform:?}"
        )))
    }
}

/// A box of half extents `half` (metres) centred on `center`, as GLB bytes: 24 vertices with
/// face normals, 36 `u16` indices, one material of base colour `color` (linear RGBA).
#[cfg(test)]
pub(crate) fn box_glb(center: [f32; 3], half: [f32; 3], color: [f32; 4]) -> Vec<u8> {
    let mut positions: Vec<f32> = Vec::new();
    let mut normals: Vec<f32> = Vec::new();
    let mut indices: Vec<u16> = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = (positions.len() / 3) as u16;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let mut p = [0.0f32; 3];
                p[axis] = sign * half[axis];
                p[u] = a * half[u];
                p[v] = b * half[v];
                let mut n = [0.0f32; 3];
                n[axis] = sign;
                positions.extend((0..3).map(|k| p[k] + center[k]));
                normals.extend(n);
            }
            // (u, v, axis) is right-handed, so the corners above run counter-clockwise seen from
            // +axis; the −axis face is wound the other way.
            let quad: [u16; 6] = if sign > 0.0 {
                [0, 1, 2, 0, 2, 3]
            } else {
                [0, 2, 1, 0, 3, 2]
            };
            indices.extend(quad.iter().map(|i| base + i));
        }
    }
    let (min, max): (Vec<f32>, Vec<f32>) = (0..3)
        .map(|k| (center[k] - half[k], center[k] + half[k]))
        .unzip();
    let mut bin: Vec<u8> = Vec::new();
    bin.extend(positions.iter().flat_map(|f| f.to_le_bytes()));
    bin.extend(normals.iter().flat_map(|f| f.to_le_bytes()));
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1},
            "indices": 2,
            "material": 0
        }]}],
        "materials": [{"pbrMetallicRoughness": {
            "baseColorFactor": color, "metallicFactor": 0.0, "roughnessFactor": 0.9
        }}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 288},
            {"buffer": 0, "byteOffset": 288, "byteLength": 288},
            {"buffer": 0, "byteOffset": 576, "byteLength": 72}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 24, "type": "VEC3",
             "min": min, "max": max},
            {"bufferView": 1, "componentType": 5126, "count": 24, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "count": 36, "type": "SCALAR"}
        ]
    });
    let mut json = serde_json::to_vec(&doc).unwrap_or_default();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[cfg(test)]
mod tests;
