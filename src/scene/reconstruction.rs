//! The reconstruction products of a [`Scene`] (issue 5): the host's own depth as an alternative to
//! stereo, the camera, depth buffers for hosts, the scene mesh and its BVH, support surfaces, and
//! the queries built on them (pick, place).
//!
//! Cache keys are chosen so that each product recomputes only for what it really depends on:
//! the camera's clip range changes the depth buffer but not the mesh; the triangle budget
//! re-simplifies the mesh but does not rebuild the grid or redetect surfaces.

use std::sync::Arc;

use glam::Vec2;

use super::Scene;
use crate::camera::{Camera, DepthEncoding, DEFAULT_HORIZONTAL_FOV_DEG};
use crate::error::{Error, Result};
use crate::image::Raster;
use crate::mesh::simplify::simplify;
use crate::mesh::{
    self, detect_surfaces_with_confidence, detect_surfaces_with_host_up, Bvh, Hit, MeshOptions,
    PlaceOptions, Placement, PlacementScene, Ray, SceneMesh, SurfaceOptions, Surfaces,
};
use crate::stereo::Disparity;
use crate::trace::{StageStatus, Trace};

/// The depth product and the camera intrinsics for it: what every geometric product starts from.
pub(super) type Base = (Arc<Raster<f32>>, Camera);

/// Depth given by the host (ARCore, a depth sensor, its own reconstruction) instead of stereo,
/// as the scene keeps it after [`Scene::set_depth`].
#[derive(Debug, Clone)]
pub struct HostDepth {
    /// Depth along the optical axis in metres, NaN where missing (NaN, ±inf, ≤ 0 and
    /// zero-confidence input values all became NaN).
    pub depth: Arc<Raster<f32>>,
    /// Confidence in [0, 1] per pixel, when the host gave one.
    pub confidence: Option<Arc<Raster<f32>>>,
    /// The host's camera intrinsics (its clip range is not used), when it gave them.
    pub camera: Option<Camera>,
}

impl Scene {
    /// Sets the host's own depth of the photo, so the scene skips stereo (the trace shows `stereo`
    /// skipped with "host depth given"). `depth` is metres along the optical axis; NaN, ±inf and
    /// values ≤ 0 mean "no depth here". `confidence` (optional, same size, in [0, 1], NaN read as
    /// 0) marks pixels of confidence 0 as missing too. `camera` gives the intrinsics the depth was
    /// measured with (its image size must be the depth's; its near/far are not used: see
    /// [`Scene::set_clip`]); without it the calibration's, else a camera of
    /// [`DEFAULT_HORIZONTAL_FOV_DEG`] (the trace warns).
    ///
    /// A map with no valid depth at all is accepted; the mesh then fails with a clear error and
    /// the surfaces are empty.
    ///
    /// # Errors
    /// `InvalidArgument` for an empty map, a confidence outside [0, 1] or a bad camera;
    /// `SizeMismatch` when the confidence, the camera or the stereo pair has another size;
    /// `TooLarge` over the context's pixel cap. On error the scene is unchanged.
    pub fn set_depth(
        &mut self,
        depth: Raster<f32>,
        confidence: Option<Raster<f32>>,
        camera: Option<Camera>,
    ) -> Result<()> {
        let (w, h) = (depth.width(), depth.height());
        if w == 0 || h == 0 {
            return Err(Error::invalid(format!(
                "host depth map is {w}x{h}: it needs at least one pixel"
            )));
        }
        self.context
            .limits()
            .check("host depth map", w as u64, h as u64)?;
        if let Some((pw, ph)) = self.photo_size() {
            if (pw as usize, ph as usize) != (w, h) {
                return Err(Error::SizeMismatch(format!(
                    "host depth map is {w}x{h} but the photo (stereo pair) is {pw}x{ph}"
                )));
            }
        }
        let confidence = match confidence {
            Some(c) => Some(Arc::new(sanitise_confidence(c, w, h)?)),
            None => None,
        };
        if let Some(c) = &camera {
            if (c.width as usize, c.height as usize) != (w, h) {
                return Err(Error::SizeMismatch(format!(
                    "host camera is for a {}x{} image but the depth map is {w}x{h}",
                    c.width, c.height
                )));
            }
            c.validate()?;
        }
        let mut depth = depth;
        for (i, z) in depth.pixels_mut().iter_mut().enumerate() {
            let trusted = confidence.as_ref().is_none_or(|c| c.pixels()[i] > 0.0);
            if !(z.is_finite() && *z > 0.0 && trusted) {
                *z = f32::NAN;
            }
        }
        self.host_depth.value = Some(HostDepth {
            depth: Arc::new(depth),
            confidence,
            camera,
        });
        self.host_depth.version = self.bump();
        Ok(())
    }

    /// Forgets the host's depth: depth comes from stereo again.
    pub fn clear_depth(&mut self) {
        self.host_depth.value = None;
        self.host_depth.version = self.bump();
    }

    /// The host's depth as the scene keeps it (sanitised), if one was set.
    pub fn host_depth(&self) -> Option<&HostDepth> {
        self.host_depth.value.as_ref()
    }

    /// Sets the camera's clip range in metres (for depth buffers and rendering), instead of the
    /// automatic one derived from the depth range ([`Camera::with_clip_from_depth`]).
    ///
    /// # Errors
    /// `InvalidArgument` unless both are finite and `0 < near < far`; the scene is unchanged.
    pub fn set_clip(&mut self, near: f32, far: f32) -> Result<()> {
        check_clip(near, far)?;
        self.clip.value = Some((near, far));
        self.clip.version = self.bump();
        Ok(())
    }

    /// Back to the clip range derived from the depth.
    pub fn clear_clip(&mut self) {
        self.clip.value = None;
        self.clip.version = self.bump();
    }

    /// Sets how depth becomes the scene mesh (grid step, discontinuity cut, triangle budget).
    ///
    /// # Errors
    /// `InvalidArgument` naming the bad field ([`MeshOptions::validate`]); the scene is unchanged.
    pub fn set_mesh_options(&mut self, options: MeshOptions) -> Result<()> {
        options.validate()?;
        self.mesh_options.value = Some(options);
        self.mesh_options.version = self.bump();
        Ok(())
    }

    /// The mesh options in use (the defaults until [`Scene::set_mesh_options`]).
    pub fn mesh_options(&self) -> MeshOptions {
        self.mesh_options.value.unwrap_or_default()
    }

    /// Sets how support surfaces are searched for (the defaults until then).
    ///
    /// # Errors
    /// `InvalidArgument` naming the bad field ([`SurfaceOptions::validate`]); the scene is
    /// unchanged.
    pub fn set_surface_options(&mut self, options: SurfaceOptions) -> Result<()> {
        options.validate()?;
        self.surface_options.value = Some(options);
        self.surface_options.version = self.bump();
        Ok(())
    }

    /// Gives gravity "up" (camera frame, any length): from an IMU or an AR runtime, which know it
    /// far better than the planes of a noisy depth map. Surfaces are then classified against it,
    /// objects stand upright along it and the lighting's "above" is it ([`Surfaces::with_host_up`]);
    /// the planes themselves are still found in the depth. Setting the up it already has changes
    /// nothing.
    ///
    /// # Errors
    /// `InvalidArgument` when `up` is not finite or has zero length; the scene is unchanged.
    pub fn set_up(&mut self, up: [f32; 3]) -> Result<()> {
        let up = crate::mesh::surfaces::validated_up(glam::Vec3::from(up))?;
        if self.host_up.value != Some(up) {
            self.host_up.value = Some(up);
            self.host_up.version = self.bump();
        }
        Ok(())
    }

    /// Back to the up estimated from the planes.
    pub fn clear_up(&mut self) {
        if self.host_up.value.take().is_some() {
            self.host_up.version = self.bump();
        }
    }

    /// The intrinsics (default clip range) of a `width × height` depth map: the host's camera,
    /// else the calibration's, else the assumed field of view.
    fn intrinsics(&self, width: u32, height: u32, trace: &mut Trace) -> Result<Camera> {
        let host = self.host_depth.value.as_ref();
        if let Some(camera) = host.and_then(|h| h.camera) {
            return Ok(camera);
        }
        match &self.calibration.value {
            Some(c) => Camera::from_calibration(c, width, height),
            None => {
                // The stereo path warned already (its depth is up to scale for the same reason).
                if host.is_some() {
                    trace.warn(format!(
                        "no camera for the host depth: assuming a {DEFAULT_HORIZONTAL_FOV_DEG}° \
                         horizontal field of view"
                    ));
                }
                Camera::assumed(width, height)
            }
        }
    }

    /// The input version the intrinsics come from.
    fn intrinsics_version(&self) -> u64 {
        match &self.host_depth.value {
            Some(HostDepth {
                camera: Some(_), ..
            }) => self.host_depth.version,
            _ => self.calibration.version,
        }
    }

    pub(super) fn depth_and_intrinsics(&mut self, trace: &mut Trace) -> Result<Base> {
        let depth = self.depth_traced(trace)?;
        let camera = self.intrinsics(depth.width() as u32, depth.height() as u32, trace)?;
        Ok((depth, camera))
    }

    /// The left camera (product `camera`): intrinsics from the host camera, the calibration or
    /// the assumed field of view; near/far from [`Scene::set_clip`], else from the depth range.
    ///
    /// # Errors
    /// As [`Scene::depth`]; `InvalidArgument` when near/far must come from a depth map with no
    /// valid depth.
    pub fn camera(&mut self) -> Result<Arc<Camera>> {
        self.traced(|scene, trace| {
            let base = scene.depth_and_intrinsics(trace)?;
            scene.camera_traced(&base, trace)
        })
    }

    pub(super) fn camera_traced(&mut self, base: &Base, trace: &mut Trace) -> Result<Arc<Camera>> {
        let (depth, intrinsics) = base;
        let intrinsics = *intrinsics;
        let versions = [
            self.depth.generation,
            self.intrinsics_version(),
            self.clip.version,
        ];
        let clip = self.clip.value;
        self.camera
            .get_or_compute("camera", &versions, trace, |_| match clip {
                Some((near, far)) => intrinsics.with_clip(near, far),
                None => intrinsics.with_clip_from_depth(depth),
            })
    }

    /// Depth encoded for a host's depth buffer with the camera's near/far (product
    /// `depth_buffer`); pixels without depth hold [`DepthEncoding::empty_value`].
    ///
    /// # Errors
    /// As [`Scene::camera`].
    pub fn depth_buffer(&mut self, encoding: DepthEncoding) -> Result<Arc<Raster<f32>>> {
        self.depth_buffer_with_clip(encoding, None)
    }

    /// [`Scene::depth_buffer`] with this call's own clip range (`Some((near, far))`, metres)
    /// instead of the camera's.
    ///
    /// # Errors
    /// As [`Scene::depth`]; `InvalidArgument` for a clip range that is not `0 < near < far`.
    pub fn depth_buffer_with_clip(
        &mut self,
        encoding: DepthEncoding,
        clip: Option<(f32, f32)>,
    ) -> Result<Arc<Raster<f32>>> {
        self.traced(|scene, trace| {
            if let Some((near, far)) = clip {
                check_clip(near, far)?;
            }
            let base = scene.depth_and_intrinsics(trace)?;
            let camera = match clip {
                Some((near, far)) => base.1.with_clip(near, far)?,
                None => *scene.camera_traced(&base, trace)?,
            };
            let depth = base.0;
            let versions = [
                scene.depth.generation,
                camera.near.to_bits() as u64,
                camera.far.to_bits() as u64,
                encoding as u64,
            ];
            scene
                .depth_buffer
                .get_or_compute("depth_buffer", &versions, trace, |_| {
                    Ok(crate::camera::depth_buffer(&depth, &camera, encoding))
                })
        })
    }

    /// The full-resolution grid mesh (before simplification): what surfaces are detected on.
    fn grid_mesh_traced(&mut self, base: &Base, trace: &mut Trace) -> Result<Arc<SceneMesh>> {
        let (depth, camera) = base;
        let options = MeshOptions {
            max_triangles: None,
            ..self.mesh_options()
        };
        // Keyed by the grid's own options, so a new triangle budget does not rebuild it.
        let versions = [
            self.depth.generation,
            self.intrinsics_version(),
            options.step as u64,
            options.max_grazing_angle_deg.to_bits() as u64,
            options.depth_noise.to_bits() as u64,
        ];
        self.grid_mesh
            .get_or_compute("mesh.grid", &versions, trace, |_| {
                SceneMesh::from_depth(depth, camera, &options)
            })
    }

    /// The scene mesh (product `mesh`): the depth grid cut at discontinuities, the normals of
    /// its vertices on a detected support surface replaced by the surface's
    /// ([`MeshOptions::snap_to_surfaces`]), simplified to [`MeshOptions::max_triangles`] when
    /// set. Sub-stages `mesh.grid`, `surfaces`, `mesh.snap` and `mesh.simplify`.
    ///
    /// # Errors
    /// As [`Scene::depth`]; `InvalidArgument` when no triangle can be formed (no valid depth, an
    /// image under 2×2 samples), with the reason.
    pub fn mesh(&mut self) -> Result<Arc<SceneMesh>> {
        self.traced(|scene, trace| {
            let base = scene.depth_and_intrinsics(trace)?;
            scene.mesh_traced(&base, trace)
        })
    }

    pub(super) fn mesh_traced(&mut self, base: &Base, trace: &mut Trace) -> Result<Arc<SceneMesh>> {
        let options = self.mesh_options();
        let grid = if options.snap_to_surfaces {
            self.snapped_mesh_traced(base, trace)?
        } else {
            trace.record(
                "mesh.snap",
                StageStatus::Skipped,
                0.0,
                "snap_to_surfaces off",
            );
            self.grid_mesh_traced(base, trace)?
        };
        let budget = options.max_triangles;
        let versions = [
            self.grid_mesh.generation,
            if options.snap_to_surfaces {
                self.snapped_mesh.generation + 1
            } else {
                0
            },
            budget.map_or(0, |b| b as u64 + 1),
        ];
        self.mesh.get_or_share("mesh", &versions, trace, |trace| {
            Ok(match budget {
                Some(b) if grid.triangle_count() > b => {
                    Arc::new(
                        trace.time("mesh.simplify", "max_triangles set", |_| simplify(&grid, b)),
                    )
                }
                _ => {
                    let why = if budget.is_some() {
                        "the grid is within max_triangles"
                    } else {
                        "no max_triangles"
                    };
                    trace.record("mesh.simplify", StageStatus::Skipped, 0.0, why);
                    grid
                }
            })
        })
    }

    /// The grid mesh with the normals of the vertices on a detected surface snapped to it
    /// ([`Surfaces::snap_mesh_normals`]; sub-stage `mesh.snap`).
    fn snapped_mesh_traced(&mut self, base: &Base, trace: &mut Trace) -> Result<Arc<SceneMesh>> {
        let grid = self.grid_mesh_traced(base, trace)?;
        let surfaces = self.surfaces_traced(base, trace)?;
        let versions = [self.grid_mesh.generation, self.surfaces.generation];
        let options = self.surface_options.value.unwrap_or_default();
        let camera = base.1;
        let confidence = self.depth_confidence(trace)?;
        self.snapped_mesh
            .get_or_compute("mesh.snap", &versions, trace, |_| {
                let mut mesh = (*grid).clone();
                surfaces.snap_mesh_normals_with_confidence(
                    &mut mesh,
                    &camera,
                    confidence.as_ref().map(DepthConfidence::raster),
                    options.membership_tolerance(),
                    options.membership_normal_tolerance_deg(),
                );
                Ok(mesh)
            })
    }

    /// The ray-query hierarchy over the scene mesh (product `bvh`).
    ///
    /// # Errors
    /// As [`Scene::mesh`].
    pub fn bvh(&mut self) -> Result<Arc<Bvh>> {
        self.traced(|scene, trace| {
            let base = scene.depth_and_intrinsics(trace)?;
            scene.bvh_traced(&base, trace)
        })
    }

    fn bvh_traced(&mut self, base: &Base, trace: &mut Trace) -> Result<Arc<Bvh>> {
        let mesh = self.mesh_traced(base, trace)?;
        let versions = [self.mesh.generation];
        self.bvh
            .get_or_compute("bvh", &versions, trace, |_| Ok(Bvh::new(&mesh)))
    }

    /// Support surfaces and the gravity "up" (product `surfaces`), detected on the unsimplified
    /// grid mesh. When no mesh can be formed from the depth (no valid depth, too small an image)
    /// the result has no surfaces and the camera's +Y as up, and the trace warns why.
    ///
    /// # Errors
    /// As [`Scene::depth`].
    pub fn surfaces(&mut self) -> Result<Arc<Surfaces>> {
        self.traced(|scene, trace| {
            let base = scene.depth_and_intrinsics(trace)?;
            scene.surfaces_traced(&base, trace)
        })
    }

    pub(super) fn surfaces_traced(
        &mut self,
        base: &Base,
        trace: &mut Trace,
    ) -> Result<Arc<Surfaces>> {
        let camera = base.1;
        // Options and camera are valid by construction, so InvalidArgument here is the depth's.
        let grid = match self.grid_mesh_traced(base, trace) {
            Ok(grid) => Some(grid),
            Err(Error::InvalidArgument(why)) => {
                trace.warn(format!("no support surfaces: {why}"));
                None
            }
            Err(e) => return Err(e),
        };
        let versions = [
            grid.is_some() as u64,
            if grid.is_some() {
                self.grid_mesh.generation
            } else {
                self.depth.generation
            },
            self.intrinsics_version(),
            self.surface_options.version,
            self.host_up.version,
        ];
        let options = self.surface_options.value.unwrap_or_default();
        let host_up = self.host_up.value;
        let empty = SceneMesh::default();
        let mesh = grid.as_deref().unwrap_or(&empty);
        // The confidence that came with the depth (the host's, or the matcher's: 0 on the holes
        // it filled), so that planes are fitted on measured depth. Both are versioned with the
        // depth.
        let confidence = self.depth_confidence(trace)?;
        let confidence = confidence.as_ref().map(DepthConfidence::raster);
        self.surfaces
            .get_or_compute("surfaces", &versions, trace, |_| match host_up {
                Some(up) => detect_surfaces_with_host_up(mesh, &camera, confidence, &options, up),
                None => detect_surfaces_with_confidence(mesh, &camera, confidence, &options),
            })
    }

    /// The scene surface seen at image position `pixel` (continuous pixels: the centre of pixel
    /// `(x, y)` is `(x + 0.5, y + 0.5)`): point, normal and distance from the camera in metres;
    /// `None` where the mesh has a hole or the pixel lies outside it.
    ///
    /// # Errors
    /// As [`Scene::mesh`]; `InvalidArgument` for a non-finite pixel.
    pub fn pick(&mut self, pixel: Vec2) -> Result<Option<Hit>> {
        self.traced(|scene, trace| {
            if !pixel.is_finite() {
                return Err(Error::invalid(format!(
                    "pick: pixel ({}, {}) is not finite",
                    pixel.x, pixel.y
                )));
            }
            let base = scene.depth_and_intrinsics(trace)?;
            let bvh = scene.bvh_traced(&base, trace)?;
            Ok(mesh::pick(&bvh, &base.1, pixel))
        })
    }

    /// Stands an object of largest side `size_m` metres, turned by `yaw_rad` about its up axis,
    /// on the surface seen at `pixel` ([`mesh::place()`]).
    ///
    /// # Errors
    /// As [`Scene::mesh`] and [`mesh::place()`] (`InvalidArgument` for a bad size or yaw, or a
    /// pixel with no surface under it).
    pub fn place(
        &mut self,
        pixel: Vec2,
        size_m: f32,
        yaw_rad: f32,
        options: &PlaceOptions,
    ) -> Result<Placement> {
        self.placing(|scene| scene.place(pixel, size_m, yaw_rad, options))
    }

    /// [`Scene::place`] for a host's own ray in the camera (= world) frame
    /// ([`mesh::place_on_ray`]).
    ///
    /// # Errors
    /// As [`Scene::place`]; `InvalidArgument` when the ray hits nothing.
    pub fn place_on_ray(
        &mut self,
        ray: &Ray,
        size_m: f32,
        yaw_rad: f32,
        options: &PlaceOptions,
    ) -> Result<Placement> {
        self.placing(|scene| scene.place_on_ray(ray, size_m, yaw_rad, options))
    }

    /// Runs `place` on what placement works on: the mesh's ray queries, the surfaces, the camera
    /// and the depth's confidence, computed or reused in one traced call.
    fn placing(
        &mut self,
        place: impl FnOnce(&PlacementScene) -> Result<Placement>,
    ) -> Result<Placement> {
        self.traced(|scene, trace| {
            let base = scene.depth_and_intrinsics(trace)?;
            let bvh = scene.bvh_traced(&base, trace)?;
            let surfaces = scene.surfaces_traced(&base, trace)?;
            let confidence = scene.depth_confidence(trace)?;
            place(&PlacementScene {
                bvh: &bvh,
                camera: &base.1,
                surfaces: &surfaces,
                confidence: confidence.as_ref().map(DepthConfidence::raster),
            })
        })
    }

    /// The confidence that came with the depth: the host's, or the matcher's (0 on the holes it
    /// filled); `None` for host depth without one. Both are versioned with the depth.
    fn depth_confidence(&mut self, trace: &mut Trace) -> Result<Option<DepthConfidence>> {
        Ok(match &self.host_depth.value {
            Some(host) => host.confidence.clone().map(DepthConfidence::Host),
            None => Some(DepthConfidence::Stereo(self.disparity_traced(trace)?)),
        })
    }
}

/// The confidence that came with the depth, shared with the product that holds it.
enum DepthConfidence {
    Host(Arc<Raster<f32>>),
    Stereo(Arc<Disparity>),
}

impl DepthConfidence {
    fn raster(&self) -> &Raster<f32> {
        match self {
            DepthConfidence::Host(c) => c,
            DepthConfidence::Stereo(d) => &d.confidence,
        }
    }
}

fn check_clip(near: f32, far: f32) -> Result<()> {
    if !(near.is_finite() && near > 0.0) {
        return Err(Error::invalid(format!(
            "clip range: near must be finite and > 0 metres, got {near}"
        )));
    }
    if !(far.is_finite() && far > near) {
        return Err(Error::invalid(format!(
            "clip range: far must be finite and > near ({near} m), got {far}"
        )));
    }
    Ok(())
}

/// Checks a host confidence map's size and range; NaN becomes 0 (no confidence).
fn sanitise_confidence(mut c: Raster<f32>, w: usize, h: usize) -> Result<Raster<f32>> {
    if (c.width(), c.height()) != (w, h) {
        return Err(Error::SizeMismatch(format!(
            "host confidence map is {}x{} but the depth map is {w}x{h}",
            c.width(),
            c.height()
        )));
    }
    for (i, v) in c.pixels_mut().iter_mut().enumerate() {
        if v.is_nan() {
            *v = 0.0;
        } else if !(0.0..=1.0).contains(v) {
            return Err(Error::invalid(format!(
                "host confidence must be in [0, 1], got {v} at pixel ({}, {})",
                i % w,
                i / w
            )));
        }
    }
    Ok(c)
}

#[cfg(test)]
mod tests;
