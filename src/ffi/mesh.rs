//! Reconstruction through the C ABI: the host's own depth, the camera and its clip range, depth
//! buffers, mesh options and the scene mesh.

use std::mem::{offset_of, size_of};

use super::boundary::{invalid, null_argument, CallError};
use super::scene::{plx_scene, with_scene};
use super::stereo::{float_view, plx_float_view};
use crate::camera::{Camera, DepthEncoding};
use crate::error::Status;
use crate::image::Raster;
use crate::mesh::MeshOptions;

/// Encodings of `plx_scene_depth_buffer`. `N`, `F` are the clip planes, `z` the depth in metres.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum plx_depth_encoding {
    /// Depth along the optical axis in metres (Unity/HoloLens linear eye depth); +inf = none.
    LinearMeters = 0,
    /// OpenGL window depth in [0, 1] (default glDepthRange), thesis eq. 3.8:
    /// `(F+N)/(2(F−N)) − F·N/((F−N)·z) + 1/2`; 1 = none.
    OpenglWindow = 1,
    /// WebGPU / Direct3D / Vulkan depth in [0, 1]: `F·(z−N)/((F−N)·z)`; 1 = none.
    WebgpuZeroToOne = 2,
    /// Reversed-Z in [0, 1]: `N·(F−z)/((F−N)·z)`, 1 at near; 0 = none.
    ReversedZ = 3,
}

/// Pinhole intrinsics of the left camera, pixels (x right, y down from the top-left corner;
/// the centre of pixel (x, y) is (x + 0.5, y + 0.5)).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_camera {
    /// Horizontal focal length, pixels (> 0).
    pub fx: f32,
    /// Vertical focal length, pixels (> 0).
    pub fy: f32,
    /// Principal point x, pixels from the left edge.
    pub cx: f32,
    /// Principal point y, pixels from the top edge.
    pub cy: f32,
}

/// Copies `height` rows of `width` floats, `stride` bytes apart, out of host memory.
unsafe fn read_grid(
    data: *const f32,
    width: u32,
    height: u32,
    stride: usize,
    name: &str,
) -> Result<Raster<f32>, CallError> {
    let row_bytes = width as usize * size_of::<f32>();
    if stride < row_bytes {
        return Err(invalid(format!(
            "{name}: stride {stride} bytes is shorter than a row of {width} floats ({row_bytes} bytes)"
        )));
    }
    let base = data.cast::<u8>();
    Ok(Raster::from_fn(width as usize, height as usize, |x, y| {
        // Unaligned reads: a host's stride need not be a multiple of 4.
        std::ptr::read_unaligned(base.add(y * stride + x * size_of::<f32>()).cast::<f32>())
    }))
}

/// Gives the scene the host's own depth of the photo (ARCore, a depth sensor, …) so that stereo
/// is skipped (the report shows `stereo` skipped, "host depth given"). `depth` holds `height` rows
/// of `width` floats, `stride_bytes` apart: metres along the optical axis, NaN, ±inf and ≤ 0 = no
/// depth. `confidence` (nullable; same size, its own stride) in [0, 1], NaN read as 0: pixels of
/// confidence 0 count as no depth. `camera` (nullable) gives the intrinsics of the depth; NULL =
/// the calibration's, else a 60° horizontal field of view. Both maps are copied.
///
/// A map without any valid depth is accepted: `plx_scene_mesh` then fails and
/// `plx_scene_surfaces` returns none. Errors: `NULL_ARGUMENT`; `INVALID_ARGUMENT` (zero size,
/// stride shorter than a row, confidence outside [0, 1], bad camera); `SIZE_MISMATCH` (the stereo
/// pair has another size); `TOO_LARGE` (over the context's pixel cap). On error the scene is
/// unchanged.
///
/// # Safety
/// `scene` is a live scene; `depth` (and `confidence` when not NULL) point to `height` readable
/// rows of their stride; `camera` is NULL or valid.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn plx_scene_set_depth(
    scene: *mut plx_scene,
    depth: *const f32,
    width: u32,
    height: u32,
    stride_bytes: usize,
    confidence: *const f32,
    confidence_stride_bytes: usize,
    camera: *const plx_camera,
) -> Status {
    with_scene(scene, |scene| {
        if depth.is_null() {
            return Err(null_argument("depth"));
        }
        if width == 0 || height == 0 {
            return Err(invalid(format!(
                "depth map is {width}x{height}: it needs at least one pixel"
            )));
        }
        // Before copying: the cap also bounds the allocation.
        scene
            .context()
            .limits()
            .check("host depth map", width as u64, height as u64)?;
        let grid = read_grid(depth, width, height, stride_bytes, "depth")?;
        let confidence = if confidence.is_null() {
            None
        } else {
            Some(read_grid(
                confidence,
                width,
                height,
                confidence_stride_bytes,
                "confidence",
            )?)
        };
        let camera = if camera.is_null() {
            None
        } else {
            let c = &*camera;
            Some(Camera::new(c.fx, c.fy, c.cx, c.cy, width, height)?)
        };
        scene.set_depth(grid, confidence, camera)?;
        Ok(())
    })
}

/// Forgets the host's depth: depth comes from the stereo pair again.
///
/// # Safety
/// `scene` is a live scene.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_clear_depth(scene: *mut plx_scene) -> Status {
    with_scene(scene, |scene| {
        scene.clear_depth();
        Ok(())
    })
}

/// Sets the camera's clip range in metres (used by depth buffers and rendering); `0, 0` = back
/// to the automatic range (half the nearest depth to twice the farthest). Errors:
/// `INVALID_ARGUMENT` unless both are finite and `0 < near < far`. On error the scene is unchanged.
///
/// # Safety
/// `scene` is a live scene.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_clip(scene: *mut plx_scene, near: f32, far: f32) -> Status {
    with_scene(scene, |scene| {
        if near == 0.0 && far == 0.0 {
            scene.clear_clip();
        } else {
            scene.set_clip(near, far)?;
        }
        Ok(())
    })
}

/// The left camera: intrinsics into `*out`, clip range in metres into `*near`, `*far` (set by
/// `plx_scene_set_clip`, else derived from the depth). Needs depth (host or stereo, computed if
/// needed). Errors: `NULL_ARGUMENT`; `NOT_AVAILABLE` without depth; `INVALID_ARGUMENT` when the
/// automatic clip range is asked of a depth map with no valid depth.
///
/// # Safety
/// `scene` is a live scene; the outputs are writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_camera(
    scene: *mut plx_scene,
    out: *mut plx_camera,
    near: *mut f32,
    far: *mut f32,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        if near.is_null() {
            return Err(null_argument("near"));
        }
        if far.is_null() {
            return Err(null_argument("far"));
        }
        let c = scene.camera()?;
        *out = plx_camera {
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
        };
        *near = c.near;
        *far = c.far;
        Ok(())
    })
}

/// Depth of the left view encoded for a host depth buffer (`encoding`: a `plx_depth_encoding`),
/// with clip planes `near`, `far` in metres, or the camera's (`plx_scene_camera`) when both are 0.
/// Pixels without depth hold the encoding's empty value (+inf, 1, 1, 0). The view is valid until
/// the scene changes. Errors: `NULL_ARGUMENT`; `INVALID_ARGUMENT` (unknown encoding, not
/// `0 < near < far`, automatic clip range of a map with no valid depth); `NOT_AVAILABLE` without
/// depth; as `plx_scene_depth` when stereo runs.
///
/// # Safety
/// `scene` is a live scene; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_depth_buffer(
    scene: *mut plx_scene,
    encoding: u32,
    near: f32,
    far: f32,
    out: *mut plx_float_view,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let encoding = match encoding {
            0 => DepthEncoding::LinearMeters,
            1 => DepthEncoding::OpenGlWindow,
            2 => DepthEncoding::WebGpuZeroToOne,
            3 => DepthEncoding::ReversedZ,
            other => return Err(invalid(format!("unknown depth encoding {other}"))),
        };
        let clip = (near != 0.0 || far != 0.0).then_some((near, far));
        let buffer = scene.depth_buffer_with_clip(encoding, clip)?;
        *out = float_view(&buffer);
        Ok(())
    })
}

/// How depth becomes the scene mesh. Initialise with `plx_mesh_options_init`, then change fields.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_mesh_options {
    /// `sizeof(plx_mesh_options)` as the caller compiled it.
    pub size: usize,
    /// Grid step in pixels: 1 = a vertex per pixel (default).
    pub step: u32,
    /// Most oblique view of a surface still meshed as continuous, degrees in (0, 90); steeper
    /// depth jumps cut the mesh (default 85).
    pub max_grazing_angle_deg: f32,
    /// Relative depth noise tolerated between neighbours, ≥ 0 (default 0.01).
    pub depth_noise: f32,
    /// Simplify to at most this many triangles (flat regions coarse, edges fine); 0 = keep the
    /// full grid (default).
    pub max_triangles: u32,
    /// Nonzero (default): the vertices on a detected support surface (floor, table, wall) take
    /// the surface's normal; 0 keeps every vertex's own fitted normal.
    pub snap_to_surfaces: u32,
}

/// Fills `options` with the defaults and its `size`.
///
/// # Safety
/// `options` is NULL or points to a writable `plx_mesh_options`.
#[no_mangle]
pub unsafe extern "C" fn plx_mesh_options_init(options: *mut plx_mesh_options) -> Status {
    super::boundary::guard(&super::handle::GLOBAL_ERROR, || {
        if options.is_null() {
            return Err(null_argument("options"));
        }
        let d = MeshOptions::default();
        *options = plx_mesh_options {
            size: size_of::<plx_mesh_options>(),
            step: d.step,
            max_grazing_angle_deg: d.max_grazing_angle_deg,
            depth_noise: d.depth_noise,
            max_triangles: 0,
            snap_to_surfaces: u32::from(d.snap_to_surfaces),
        };
        Ok(())
    })
}

/// Reads the fields the caller's struct version has; the others keep their defaults.
unsafe fn read_mesh_options(options: *const plx_mesh_options) -> Result<MeshOptions, CallError> {
    let size = std::ptr::read_unaligned(options.cast::<usize>());
    if size < size_of::<usize>() {
        return Err(invalid(format!(
            "options.size is {size}: set it with plx_mesh_options_init"
        )));
    }
    let base = options.cast::<u8>();
    let word = |offset: usize| -> Option<[u8; 4]> {
        (size >= offset + 4).then(|| std::ptr::read_unaligned(base.add(offset).cast::<[u8; 4]>()))
    };
    let mut out = MeshOptions::default();
    if let Some(b) = word(offset_of!(plx_mesh_options, step)) {
        out.step = u32::from_ne_bytes(b);
    }
    if let Some(b) = word(offset_of!(plx_mesh_options, max_grazing_angle_deg)) {
        out.max_grazing_angle_deg = f32::from_ne_bytes(b);
    }
    if let Some(b) = word(offset_of!(plx_mesh_options, depth_noise)) {
        out.depth_noise = f32::from_ne_bytes(b);
    }
    if let Some(b) = word(offset_of!(plx_mesh_options, max_triangles)) {
        let budget = u32::from_ne_bytes(b);
        out.max_triangles = (budget > 0).then_some(budget as usize);
    }
    if let Some(b) = word(offset_of!(plx_mesh_options, snap_to_surfaces)) {
        out.snap_to_surfaces = u32::from_ne_bytes(b) != 0;
    }
    Ok(out)
}

/// Sets the mesh options (NULL = back to the defaults). Errors: `INVALID_ARGUMENT` naming a field
/// out of range. On error the scene is unchanged.
///
/// # Safety
/// `scene` is a live scene; `options` is NULL or valid for `options->size` bytes.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_mesh_options(
    scene: *mut plx_scene,
    options: *const plx_mesh_options,
) -> Status {
    with_scene(scene, |scene| {
        let options = if options.is_null() {
            MeshOptions::default()
        } else {
            read_mesh_options(options)?
        };
        scene.set_mesh_options(options)?;
        Ok(())
    })
}

/// A borrowed triangle mesh in library memory, in the camera (= world) frame of DESIGN.md
/// (metres; +X right, +Y up, the camera looks along −Z). Triangles are counter-clockwise seen
/// from the camera. Valid until the next call that changes the scene it came from.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct plx_mesh_view {
    /// `3 · vertex_count` floats: x, y, z per vertex, metres.
    pub positions: *const f32,
    /// `3 · vertex_count` floats: unit smooth normals (on a detected support surface the
    /// surface's normal, unless `snap_to_surfaces` is 0 in the mesh options).
    pub normals: *const f32,
    /// `4 · vertex_count` floats: unit tangents along the photo's u, bitangent sign in w (glTF).
    pub tangents: *const f32,
    /// `2 · vertex_count` floats: texture coordinates into the photo, (0, 0) top-left, (1, 1)
    /// bottom-right.
    pub uvs: *const f32,
    /// Number of vertices.
    pub vertex_count: usize,
    /// `index_count` vertex indices, three per triangle, each `< vertex_count`.
    pub indices: *const u32,
    /// Number of indices (3 × triangles).
    pub index_count: usize,
}

/// The scene mesh: the depth grid cut at depth discontinuities, holes where depth is missing,
/// simplified to `max_triangles` when set (`plx_scene_set_mesh_options`). Computed from depth
/// (host or stereo) unless nothing it depends on changed. Never holds a NaN or an index out of
/// range. Errors: `NULL_ARGUMENT`; `NOT_AVAILABLE` without depth; `INVALID_ARGUMENT` when no
/// triangle can be formed (no valid depth, an image under 2×2 samples), the message says which.
///
/// # Safety
/// `scene` is a live scene; `out` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_mesh(scene: *mut plx_scene, out: *mut plx_mesh_view) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let mesh = scene.mesh()?;
        *out = plx_mesh_view {
            positions: mesh.positions.as_ptr().cast(),
            normals: mesh.normals.as_ptr().cast(),
            tangents: mesh.tangents.as_ptr().cast(),
            uvs: mesh.uvs.as_ptr().cast(),
            vertex_count: mesh.vertex_count(),
            indices: mesh.indices.as_ptr(),
            index_count: mesh.indices.len(),
        };
        Ok(())
    })
}
