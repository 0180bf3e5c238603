//! Lighting through the C ABI: the host's lights, ambient SH9 and environment map replacing the
//! estimates.

use super::boundary::{invalid, null_argument, optional_floats, CallError};
use super::image::{plx_image, view};
use super::image_io::{plx_image_out, write_linear};
use super::scene::{plx_scene, with_scene};
use crate::error::Status;
use crate::light::{Light, LightKind, Sh9, CUBE_FACES};
use crate::scene::MAX_LIGHTS;

/// Kinds of `plx_light::kind`.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum plx_light_kind {
    /// Infinitely far away: `direction` and the angular size in degrees.
    Directional = 0,
    /// A sphere of diameter `size` metres at `position` (0 = a point).
    Point = 1,
    /// A one-sided disc of diameter `size` metres at `position`, emitting along `direction`.
    Area = 2,
}

/// One light, in the left camera's frame (+X right, +Y up, the camera looks along −Z; metres).
/// `intensity` is linear RGB relative to the photo's exposure: for a directional light the
/// irradiance on a surface facing it, for point and area lights the radiant intensity (per
/// steradian; along the axis of an area light).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct plx_light {
    /// A `plx_light_kind` value.
    pub kind: u32,
    /// Centre, metres (ignored for directional lights).
    pub position: [f32; 3],
    /// Unit direction the light travels (from the light to the scene); ignored for point lights.
    pub direction: [f32; 3],
    /// Diameter in metres (point, area) or full angular diameter in degrees (directional,
    /// [0, 90)); 0 = hard shadows.
    pub size: f32,
    /// Linear RGB intensity, every channel ≥ 0.
    pub intensity: [f32; 3],
    /// Confidence of an estimate in [0, 1] (1 for the host's lights).
    pub confidence: f32,
}

pub(crate) fn light_kind(code: u32) -> Result<LightKind, CallError> {
    match code {
        0 => Ok(LightKind::Directional),
        1 => Ok(LightKind::Point),
        2 => Ok(LightKind::Area),
        other => Err(invalid(format!(
            "unknown light kind {other} (0 directional, 1 point, 2 area)"
        ))),
    }
}

impl plx_light {
    pub(crate) fn from_light(light: &Light) -> plx_light {
        plx_light {
            kind: light.kind as u32,
            position: light.position,
            direction: light.direction,
            size: light.size,
            intensity: light.intensity,
            confidence: light.confidence,
        }
    }

    fn to_light(self) -> Result<Light, CallError> {
        Ok(Light {
            kind: light_kind(self.kind)?,
            position: self.position,
            direction: self.direction,
            size: self.size,
            intensity: self.intensity,
            confidence: self.confidence,
        })
    }
}

/// Replaces the estimated lights with `count` lights at `lights` (copied). `count` 0 (`lights`
/// may then be NULL) means no direct light at all: only the ambient term lights the artefacts.
/// To adjust one estimated light, read them with `plx_scene_lights`, change it and set them all.
/// Errors: `NULL_ARGUMENT`; `INVALID_ARGUMENT` naming the light and field (unknown kind, a
/// non-finite value, zero direction, negative size or intensity, angular size ≥ 90°, confidence
/// outside [0, 1]) or more than 64 lights. On error the scene is unchanged.
///
/// # Safety
/// `scene` is a live scene; `lights` points to `count` readable `plx_light`s (or is NULL when
/// `count` is 0).
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_lights(
    scene: *mut plx_scene,
    lights: *const plx_light,
    count: usize,
) -> Status {
    with_scene(scene, |scene| {
        if count > MAX_LIGHTS {
            return Err(invalid(format!(
                "{count} lights given, at most {MAX_LIGHTS} are supported"
            )));
        }
        if count > 0 && lights.is_null() {
            return Err(null_argument("lights"));
        }
        let given = if count == 0 {
            &[][..]
        } else {
            std::slice::from_raw_parts(lights, count)
        };
        let converted = given
            .iter()
            .enumerate()
            .map(|(i, l)| {
                l.to_light().map_err(|mut e| {
                    e.message = format!("light {i}: {}", e.message);
                    e
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        scene.set_lights(converted)?;
        Ok(())
    })
}

/// Back to the estimated lights.
///
/// # Safety
/// `scene` is a live scene.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_reset_lights(scene: *mut plx_scene) -> Status {
    with_scene(scene, |scene| {
        scene.clear_lights();
        Ok(())
    })
}

/// Replaces the estimated ambient light with 27 floats at `sh9`: nine RGB spherical-harmonics
/// coefficients in ARCore's order (coefficient-major, RGB each), in Filament's pre-scaled
/// irradiance convention: the diffuse radiance of a white surface with unit normal n is
/// `c0 + c1·y + c2·z + c3·x + c4·xy + c5·yz + c6·(3z² − 1) + c7·xz + c8·(x² − y²)`. NULL = back to
/// the estimate. Errors: `INVALID_ARGUMENT` for a non-finite coefficient (the scene is unchanged).
///
/// # Safety
/// `scene` is a live scene; `sh9` is NULL or points to 27 readable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_sh9(scene: *mut plx_scene, sh9: *const f32) -> Status {
    with_scene(scene, |scene| {
        match optional_floats::<27>(sh9) {
            Some(values) => scene.set_sh9(Sh9::from_array(&values)?)?,
            None => scene.clear_sh9(),
        }
        Ok(())
    })
}

/// Names where the host will put its objects, `point[3]` in the camera frame (metres, +X right,
/// +Y up, −Z forward): the estimated environment (and so the ambient SH9 and what glossy
/// materials reflect) is the photo re-projected around it. NULL = back to the default (the median
/// point of the up-facing surfaces, 2 cm above them). Setting it re-estimates the lighting on the
/// next query but not the depth or mesh. Errors: `INVALID_ARGUMENT` for a non-finite coordinate
/// (the scene is unchanged).
///
/// # Safety
/// `scene` is a live scene; `point` is NULL or points to 3 readable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_insertion_point(
    scene: *mut plx_scene,
    point: *const f32,
) -> Status {
    with_scene(scene, |scene| {
        match optional_floats::<3>(point) {
            Some(xyz) => scene.set_insertion_point(xyz)?,
            None => scene.clear_insertion_point(),
        }
        Ok(())
    })
}

/// Replaces the estimated environment with the host's equirectangular map (copied): twice as
/// wide as high, the centre column looking along −Z (the camera's view), the top row +Y, in the
/// camera frame. Float formats are linear radiance relative to the photo's exposure; 8-bit
/// formats are decoded from sRGB (no inverse tone mapping: give a float map for HDR). Float
/// values are read as every float image is: NaN and negatives as 0, +inf as the largest float
/// (the SH projection clamps very bright texels, so it stays finite). NULL = back to the
/// estimate. Errors: `NULL_ARGUMENT` (`image->data`); `INVALID_ARGUMENT` (not 2:1, bad format or
/// stride); `TOO_LARGE` over the context's pixel cap. On error the scene is unchanged.
///
/// # Safety
/// `scene` is a live scene; `image` is NULL or a valid `plx_image`.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_set_environment_equirect(
    scene: *mut plx_scene,
    image: *const plx_image,
) -> Status {
    with_scene(scene, |scene| {
        if image.is_null() {
            scene.clear_environment();
            return Ok(());
        }
        let view = view(image, "image")?;
        scene.context().limits().check(
            "environment map",
            view.width() as u64,
            view.height() as u64,
        )?;
        scene.set_environment_equirect(view.to_linear_rgb())?;
        Ok(())
    })
}

/// The lights in use (the host's, else the estimated ones): the total into `*count`, and the
/// first `min(capacity, total)` into `out` (NULL allowed when `capacity` is 0: ask for the count
/// first). Errors: `NULL_ARGUMENT`; `NOT_AVAILABLE` without a photo or depth when estimating; as
/// `plx_scene_depth`.
///
/// # Safety
/// `scene` is a live scene; `out` points to `capacity` writable `plx_light`s (or is NULL with
/// `capacity` 0); `count` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_lights(
    scene: *mut plx_scene,
    out: *mut plx_light,
    capacity: usize,
    count: *mut usize,
) -> Status {
    with_scene(scene, |scene| {
        if count.is_null() {
            return Err(null_argument("count"));
        }
        if capacity > 0 && out.is_null() {
            return Err(null_argument("out"));
        }
        let lights = scene.lights()?;
        for (i, light) in lights.iter().take(capacity).enumerate() {
            *out.add(i) = plx_light::from_light(light);
        }
        *count = lights.len();
        Ok(())
    })
}

/// The main light, as AR platforms give it: `direction[3]` the unit vector from the scene towards
/// the light (for a point or area light, towards its centre from the insertion point: the host's
/// (`plx_scene_set_insertion_point`) when set; else, for estimated lights, the estimate's, and for
/// host lights, 2 m in front of the camera), `rgb[3]` its intensity (see `plx_light`). With an
/// empty host light list both are zero. Errors as `plx_scene_lights`.
///
/// # Safety
/// `scene` is a live scene; `direction` and `rgb` point to 3 writable floats each.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_main_light(
    scene: *mut plx_scene,
    direction: *mut f32,
    rgb: *mut f32,
) -> Status {
    with_scene(scene, |scene| {
        if direction.is_null() {
            return Err(null_argument("direction"));
        }
        if rgb.is_null() {
            return Err(null_argument("rgb"));
        }
        let (dir, intensity) = match scene.main_light()? {
            Some(light) => {
                let origin = glam::Vec3::from(scene.main_light_origin()?);
                (light.towards(origin).0.to_array(), light.intensity)
            }
            None => ([0.0; 3], [0.0; 3]),
        };
        std::ptr::copy_nonoverlapping(dir.as_ptr(), direction, 3);
        std::ptr::copy_nonoverlapping(intensity.as_ptr(), rgb, 3);
        Ok(())
    })
}

/// The ambient light as 27 floats into `out` (the convention of `plx_scene_set_sh9`): the
/// host's, else projected from the environment. Errors as `plx_scene_lights`.
///
/// # Safety
/// `scene` is a live scene; `out` points to 27 writable floats.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_sh9(scene: *mut plx_scene, out: *mut f32) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        let values = scene.sh9()?.to_array();
        std::ptr::copy_nonoverlapping(values.as_ptr(), out, 27);
        Ok(())
    })
}

/// Edge length in texels of each face of the environment cube that `plx_scene_environment_cube_face`
/// writes. Errors as `plx_scene_lights` (the environment is estimated from the photo unless the
/// host gave one).
///
/// # Safety
/// `scene` is a live scene; `size` is writable.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_environment_cube_size(
    scene: *mut plx_scene,
    size: *mut u32,
) -> Status {
    with_scene(scene, |scene| {
        if size.is_null() {
            return Err(null_argument("size"));
        }
        let environment = scene.environment()?;
        *size = environment.cube.levels.first().map_or(0, |l| l.size);
        Ok(())
    })
}

/// Writes face `face` of the environment cube (linear radiance relative to the photo's white, in
/// the left camera's frame) into `out`, a square image of `plx_scene_environment_cube_size`
/// texels in any `plx_pixel_format` (`PLX_PIXEL_FORMAT_RGBA_F16` for a GPU's RGBA16F cube; alpha
/// 1; 8-bit formats clip at 1 and are sRGB-encoded). Faces in GPU array-layer order: 0 +X, 1 −X,
/// 2 +Y, 3 −Y, 4 +Z, 5 −Z, each oriented as Vulkan, D3D and WebGPU sample cube maps (row 0 at
/// the top of the face). The host's map (`plx_scene_set_environment_equirect`) when given, else
/// the estimate. Errors: `NULL_ARGUMENT`; `INVALID_ARGUMENT` (face > 5, unknown format, short
/// stride); `SIZE_MISMATCH` (`out` is not the face's size); as `plx_scene_lights`. On error `out`
/// is untouched.
///
/// # Safety
/// `scene` is a live scene; `out` points to a valid descriptor of writable memory.
#[no_mangle]
pub unsafe extern "C" fn plx_scene_environment_cube_face(
    scene: *mut plx_scene,
    face: u32,
    out: *const plx_image_out,
) -> Status {
    with_scene(scene, |scene| {
        if out.is_null() {
            return Err(null_argument("out"));
        }
        if face as usize >= CUBE_FACES {
            return Err(invalid(format!(
                "cube face {face} does not exist (0 +X, 1 −X, 2 +Y, 3 −Y, 4 +Z, 5 −Z)"
            )));
        }
        let environment = scene.environment()?;
        let level = environment
            .cube
            .levels
            .first()
            .ok_or_else(|| invalid("the environment cube has no level"))?;
        let n = level.size as usize;
        let texels = level
            .texels
            .get(face as usize * n * n..(face as usize + 1) * n * n)
            .ok_or_else(|| invalid("the environment cube is shorter than six faces"))?;
        write_linear(out, "out", level.size, level.size, |x, y| {
            let [r, g, b] = texels[y * n + x];
            [r, g, b, 1.0]
        })
    })
}
