//! The scene description: what a reference render is made of, as plain serde types (JSON).
//!
//! A scene is a rectified stereo camera rig, objects (a procedural shape or a triangle mesh, a
//! material and a transform each), lights and an environment. World space is right-handed, +Y up,
//! metres. Light is linear and relative to the exposure: a white diffuse surface that receives an
//! irradiance of π renders as 1.0.
//!
//! Example (JSON):
//! ```json
//! {
//!   "name": "demo",
//!   "camera": {"width": 320, "height": 240, "fov_x_deg": 60, "baseline_m": 0.058,
//!              "position": [0, 1.4, 2], "look_at": [0, 0.8, 0]},
//!   "objects": [{"shape": {"type": "plane", "size": [4, 4]},
//!                "material": {"base_color": [0.6, 0.6, 0.6],
//!                             "texture": {"pattern": {"type": "checker"}, "scale": 4, "color": [0.2, 0.2, 0.2]}}}],
//!   "lights": [{"type": "sphere", "center": [0, 2, 0], "radius": 0.1, "radiance": [50, 50, 50]}],
//!   "environment": {"type": "constant", "radiance": [0.05, 0.05, 0.05]}
//! }
//! ```

use glam::{EulerRot, Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

use crate::error::{Error, Result};

/// A scene to render: camera rig, objects, lights and environment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// A name for reports and file names.
    #[serde(default)]
    pub name: String,
    /// The stereo rig.
    pub camera: CameraRig,
    /// Everything that reflects light.
    #[serde(default)]
    pub objects: Vec<Object>,
    /// Emitters sampled explicitly (next-event estimation).
    #[serde(default)]
    pub lights: Vec<Light>,
    /// Radiance arriving from infinitely far away.
    #[serde(default)]
    pub environment: Environment,
    /// Openings (windows, doors) through which the environment and the directional lights shine
    /// into an interior. Optional: they guide the sampling of that light (far less noise in a
    /// room lit through a window) and never change what the image converges to.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub portals: Vec<Portal>,
}

/// A rectified stereo rig: two identical pinhole cameras side by side (no convergence), the right
/// one `baseline_m` along the left camera's +X axis. The principal point is the image centre.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraRig {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Horizontal field of view in degrees (used when `focal_px` is absent; default 60).
    #[serde(default)]
    pub fov_x_deg: Option<f64>,
    /// Focal length in pixels at `width`; wins over `fov_x_deg`.
    #[serde(default)]
    pub focal_px: Option<f64>,
    /// Distance between the two camera centres, metres (default 0.058, the thesis' rig).
    #[serde(default = "default_baseline")]
    pub baseline_m: f64,
    /// Left camera centre, world metres.
    pub position: [f32; 3],
    /// A point the left camera looks at.
    pub look_at: [f32; 3],
    /// The world direction that appears up in the image (default +Y).
    #[serde(default = "default_up")]
    pub up: [f32; 3],
}

fn default_baseline() -> f64 {
    0.058
}
fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// One object: a shape, its material and where it stands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Object {
    /// A name for reports (optional).
    #[serde(default)]
    pub name: String,
    /// The geometry in object space.
    pub shape: Shape,
    /// Its surface.
    #[serde(default)]
    pub material: Material,
    /// Object space → world.
    #[serde(default)]
    pub transform: Transform,
}

/// Scale, then rotation (yaw about +Y, pitch about +X, roll about +Z, in that order of
/// application from the outside in: `R = Ry(yaw) · Rx(pitch) · Rz(roll)`), then translation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Transform {
    /// Metres.
    #[serde(default)]
    pub translation: [f32; 3],
    /// Yaw, pitch, roll in degrees.
    #[serde(default)]
    pub rotation_deg: [f32; 3],
    /// Per-axis scale (default 1).
    #[serde(default = "default_scale")]
    pub scale: [f32; 3],
}

fn default_scale() -> [f32; 3] {
    [1.0; 3]
}

impl Default for Transform {
    fn default() -> Self {
        Transform {
            translation: [0.0; 3],
            rotation_deg: [0.0; 3],
            scale: [1.0; 3],
        }
    }
}

impl Transform {
    /// A pure translation.
    pub fn at(x: f32, y: f32, z: f32) -> Transform {
        Transform {
            translation: [x, y, z],
            ..Transform::default()
        }
    }

    /// The rotation part.
    pub fn rotation(&self) -> Quat {
        let [yaw, pitch, roll] = self.rotation_deg.map(f32::to_radians);
        Quat::from_euler(EulerRot::YXZ, yaw, pitch, roll)
    }

    /// The object → world matrix.
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(
            Vec3::from(self.scale),
            self.rotation(),
            Vec3::from(self.translation),
        )
    }
}

/// Geometry in object space. Every shape is centred on the origin unless said otherwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// A rectangle in the XZ plane facing +Y, `size = [x extent, z extent]` metres.
    Plane {
        /// Extents along X and Z, metres.
        size: [f32; 2],
    },
    /// An axis-aligned box with extents `size` metres.
    Box {
        /// Extents along X, Y, Z, metres.
        size: [f32; 3],
    },
    /// A sphere of `radius` metres (UV-tessellated with smooth normals).
    Sphere {
        /// Radius, metres.
        radius: f32,
        /// Segments around the equator (default 48; rings are half of that).
        #[serde(default)]
        segments: Option<u32>,
    },
    /// A capped cylinder along +Y, from −height/2 to +height/2.
    Cylinder {
        /// Radius, metres.
        radius: f32,
        /// Height, metres.
        height: f32,
        /// Segments around (default 48).
        #[serde(default)]
        segments: Option<u32>,
    },
    /// A torus around +Y in the XZ plane.
    Torus {
        /// Distance from the centre to the tube's centre line, metres.
        major_radius: f32,
        /// Tube radius, metres.
        minor_radius: f32,
        /// Segments around the ring (default 48; the tube gets half of that).
        #[serde(default)]
        segments: Option<u32>,
    },
    /// Any triangle mesh: vertex positions (metres, object space) and index triples.
    Mesh {
        /// Vertex positions.
        positions: Vec<[f32; 3]>,
        /// Triangles as vertex index triples (counter-clockwise = front).
        indices: Vec<[u32; 3]>,
        /// Optional per-vertex normals (smooth shading); flat shading without them.
        #[serde(default)]
        normals: Option<Vec<[f32; 3]>>,
    },
}

/// The glTF 2.0 metallic-roughness material (spec Appendix B), with an optional procedural
/// texture on the base colour and an emission.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Linear base colour (albedo for dielectrics, F0 for metals), each in [0, 1].
    #[serde(default = "default_base_color")]
    pub base_color: [f32; 3],
    /// Procedural variation of the base colour.
    #[serde(default)]
    pub texture: Option<Texture>,
    /// 0 = dielectric, 1 = metal.
    #[serde(default)]
    pub metallic: f32,
    /// Perceptual roughness in [0, 1] (α = roughness²).
    #[serde(default = "default_roughness")]
    pub roughness: f32,
    /// Strength of the dielectric specular layer in [0, 1] (the `specular` factor of
    /// KHR_materials_specular; default 1 = plain glTF). 0 gives a pure Lambertian surface.
    #[serde(default = "default_one")]
    pub specular: f32,
    /// Emitted radiance (linear, ≥ 0), found by paths that hit the surface (not sampled as a light).
    #[serde(default)]
    pub emission: [f32; 3],
}

fn default_base_color() -> [f32; 3] {
    [0.8; 3]
}
fn default_roughness() -> f32 {
    1.0
}

impl Default for Material {
    fn default() -> Self {
        Material {
            base_color: default_base_color(),
            texture: None,
            metallic: 0.0,
            roughness: default_roughness(),
            specular: 1.0,
            emission: [0.0; 3],
        }
    }
}

impl Material {
    /// A diffuse (roughness 1, metallic 0) glTF material of this colour.
    pub fn diffuse(base_color: [f32; 3]) -> Material {
        Material {
            base_color,
            ..Material::default()
        }
    }

    /// A pure Lambertian material (no specular layer): reflects `albedo` of the incident light.
    pub fn lambert(albedo: [f32; 3]) -> Material {
        Material {
            base_color: albedo,
            specular: 0.0,
            ..Material::default()
        }
    }
}

/// A solid (3D) procedural texture evaluated at the object-space point (scaled with the object):
/// `colour = mix(base_color, color, pattern(p · scale)) · (1 + speckle · (2h − 1))`, with `h` a
/// fine random value per 2 mm cell, so that even uniform areas carry texture for stereo matching.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Texture {
    /// The pattern in [0, 1] that mixes the two colours.
    pub pattern: Pattern,
    /// Pattern cells per metre.
    #[serde(default = "default_texture_scale")]
    pub scale: f32,
    /// The second colour (linear).
    pub color: [f32; 3],
    /// Relative amplitude of the fine speckle in [0, 1].
    #[serde(default)]
    pub speckle: f32,
}

fn default_texture_scale() -> f32 {
    1.0
}

/// Procedural patterns.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Pattern {
    /// 3D checkerboard, cells of 1/scale metres.
    Checker,
    /// Fractal value noise (`octaves` ≥ 1, default 4).
    Noise {
        /// Number of octaves.
        #[serde(default)]
        octaves: Option<u32>,
    },
    /// Wood-like stripes: growth rings around an axis parallel to X, distorted by noise.
    Wood,
    /// Random value per cell.
    Speckle,
}

/// Emitters that are sampled explicitly. Radiance is linear, relative to the exposure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Light {
    /// A one-sided parallelogram: corners `center ± edge_u/2 ± edge_v/2`, emitting towards
    /// `edge_u × edge_v`.
    Rect {
        /// Centre, world metres.
        center: [f32; 3],
        /// First edge (full length), metres.
        edge_u: [f32; 3],
        /// Second edge (full length), metres.
        edge_v: [f32; 3],
        /// Emitted radiance.
        radiance: [f32; 3],
    },
    /// A sphere emitting uniformly. Its radiant intensity is `π · radius² · radiance`.
    Sphere {
        /// Centre, world metres.
        center: [f32; 3],
        /// Radius, metres (> 0).
        radius: f32,
        /// Emitted radiance.
        radiance: [f32; 3],
    },
    /// Light from infinitely far away in a cone of `angular_diameter_deg` (0 = a delta light,
    /// the sun is about 0.53°).
    Directional {
        /// The direction the light travels (from the light towards the scene), world.
        direction: [f32; 3],
        /// Irradiance on a surface facing the light.
        irradiance: [f32; 3],
        /// Full angular diameter of the source, degrees, in [0, 90).
        #[serde(default)]
        angular_diameter_deg: f32,
    },
}

/// An opening through which distant light enters, like Cycles' light portals: the parallelogram
/// with corners `center ± edge_u/2 ± edge_v/2`. It is neither geometry nor an emitter; place it
/// across the opening (for a window in a wall, on the wall's outer face).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Portal {
    /// Centre, world metres.
    pub center: [f32; 3],
    /// First edge (full length), metres.
    pub edge_u: [f32; 3],
    /// Second edge (full length), metres.
    pub edge_v: [f32; 3],
}

/// Radiance from infinitely far away in every direction not covered by a light.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Environment {
    /// Nothing.
    #[default]
    Black,
    /// The same radiance from every direction.
    Constant {
        /// Radiance.
        radiance: [f32; 3],
    },
    /// A sky: `horizon` at the horizon blending to `zenith` straight up, `ground` below.
    Sky {
        /// Radiance straight up.
        zenith: [f32; 3],
        /// Radiance at the horizon.
        horizon: [f32; 3],
        /// Radiance from below the horizon.
        ground: [f32; 3],
    },
    /// An equirectangular (latitude-longitude) HDR or EXR file: image x ↦ azimuth, the centre
    /// column looks along −Z, +X at three quarters; image y ↦ polar angle, the top row is +Y.
    Equirect {
        /// The file (Radiance HDR or OpenEXR).
        path: PathBuf,
        /// Multiplier on the file's values (default 1).
        #[serde(default = "default_one")]
        scale: f32,
        /// Rotation about +Y in degrees.
        #[serde(default)]
        rotation_deg: f32,
    },
}

fn default_one() -> f32 {
    1.0
}

fn finite3(what: &str, v: [f32; 3]) -> Result<()> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(Error::invalid(format!("{what} must be finite, got {v:?}")))
    }
}

fn colour(what: &str, v: [f32; 3]) -> Result<()> {
    if v.iter().all(|c| c.is_finite() && *c >= 0.0) {
        Ok(())
    } else {
        Err(Error::invalid(format!(
            "{what} must be finite and >= 0, got {v:?}"
        )))
    }
}

fn positive(what: &str, v: f32) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(format!(
            "{what} must be finite and > 0, got {v}"
        )))
    }
}

impl Scene {
    /// Parses a scene from JSON and validates it.
    ///
    /// # Errors
    /// `Format` for malformed JSON (with line and column), `InvalidArgument` as [`Scene::validate`].
    pub fn from_json(text: &str) -> Result<Scene> {
        let scene: Scene = serde_json::from_str(text)
            .map_err(|e| Error::format(format!("scene description: {e}")))?;
        scene.validate()?;
        Ok(scene)
    }

    /// Reads and parses a JSON scene file. Relative `Equirect` paths are taken relative to the
    /// file's folder.
    ///
    /// # Errors
    /// `Io`, or as [`Scene::from_json`].
    pub fn load(path: impl AsRef<std::path::Path>) -> Result<Scene> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut scene = Scene::from_json(&text).map_err(|e| match e {
            Error::Format(m) => Error::Format(format!("{}: {m}", path.display())),
            other => other,
        })?;
        if let Environment::Equirect { path: env, .. } = &mut scene.environment {
            if env.is_relative() {
                if let Some(dir) = path.parent() {
                    *env = dir.join(&*env);
                }
            }
        }
        Ok(scene)
    }

    /// Pretty JSON of this scene.
    pub fn to_json(&self) -> String {
        // Plain structs of numbers and strings always serialise.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Checks every value against its documented range.
    ///
    /// # Errors
    /// `InvalidArgument` naming the object, light or field that is out of range.
    pub fn validate(&self) -> Result<()> {
        self.camera.validate()?;
        for (i, o) in self.objects.iter().enumerate() {
            let name = if o.name.is_empty() {
                format!("object {i}")
            } else {
                format!("object {i} ({})", o.name)
            };
            o.validate().map_err(|e| match e {
                Error::InvalidArgument(m) => Error::invalid(format!("{name}: {m}")),
                other => other,
            })?;
        }
        for (i, l) in self.lights.iter().enumerate() {
            l.validate().map_err(|e| match e {
                Error::InvalidArgument(m) => Error::invalid(format!("light {i}: {m}")),
                other => other,
            })?;
        }
        for (i, p) in self.portals.iter().enumerate() {
            p.validate().map_err(|e| match e {
                Error::InvalidArgument(m) => Error::invalid(format!("portal {i}: {m}")),
                other => other,
            })?;
        }
        self.environment.validate()
    }
}

impl Portal {
    fn validate(&self) -> Result<()> {
        finite3("center", self.center)?;
        finite3("edge_u", self.edge_u)?;
        finite3("edge_v", self.edge_v)?;
        let area = Vec3::from(self.edge_u)
            .cross(Vec3::from(self.edge_v))
            .length();
        positive("portal area (|edge_u × edge_v|)", area)
    }
}

impl CameraRig {
    /// Focal length in pixels at the rig's own width.
    pub fn focal_px(&self) -> f64 {
        match self.focal_px {
            Some(f) => f,
            None => {
                let fov = self.fov_x_deg.unwrap_or(60.0).to_radians();
                self.width as f64 / 2.0 / (fov / 2.0).tan()
            }
        }
    }

    /// Checks sizes, focal length, baseline and pose.
    ///
    /// # Errors
    /// `InvalidArgument` naming the bad field.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::invalid(format!(
                "camera: size {}x{} has a zero dimension",
                self.width, self.height
            )));
        }
        if let Some(fov) = self.fov_x_deg {
            if !(fov.is_finite() && fov > 0.0 && fov < 179.0) {
                return Err(Error::invalid(format!(
                    "camera: fov_x_deg must be in (0, 179), got {fov}"
                )));
            }
        }
        if let Some(f) = self.focal_px {
            if !(f.is_finite() && f > 0.0) {
                return Err(Error::invalid(format!(
                    "camera: focal_px must be finite and > 0, got {f}"
                )));
            }
        }
        if !(self.baseline_m.is_finite() && self.baseline_m > 0.0) {
            return Err(Error::invalid(format!(
                "camera: baseline_m must be finite and > 0, got {}",
                self.baseline_m
            )));
        }
        finite3("camera position", self.position)?;
        finite3("camera look_at", self.look_at)?;
        finite3("camera up", self.up)?;
        let forward = Vec3::from(self.look_at) - Vec3::from(self.position);
        if forward.length() < 1e-6 {
            return Err(Error::invalid(
                "camera: look_at must differ from position".to_string(),
            ));
        }
        if forward.normalize().cross(Vec3::from(self.up)).length() < 1e-6 {
            return Err(Error::invalid(
                "camera: up must not be parallel to the viewing direction".to_string(),
            ));
        }
        Ok(())
    }
}

impl Object {
    fn validate(&self) -> Result<()> {
        self.shape.validate()?;
        self.material.validate()?;
        let t = &self.transform;
        finite3("translation", t.translation)?;
        finite3("rotation_deg", t.rotation_deg)?;
        for s in t.scale {
            positive("scale", s)?;
        }
        Ok(())
    }
}

/// The most segments any procedural shape may ask for.
pub const MAX_SEGMENTS: u32 = 4096;

impl Shape {
    fn validate(&self) -> Result<()> {
        let segments = |s: Option<u32>| match s {
            Some(n) if !(3..=MAX_SEGMENTS).contains(&n) => Err(Error::invalid(format!(
                "segments must be in 3..={MAX_SEGMENTS}, got {n}"
            ))),
            _ => Ok(()),
        };
        match self {
            Shape::Plane { size } => size.iter().try_for_each(|s| positive("plane size", *s)),
            Shape::Box { size } => size.iter().try_for_each(|s| positive("box size", *s)),
            Shape::Sphere {
                radius,
                segments: s,
            } => {
                positive("sphere radius", *radius)?;
                segments(*s)
            }
            Shape::Cylinder {
                radius,
                height,
                segments: s,
            } => {
                positive("cylinder radius", *radius)?;
                positive("cylinder height", *height)?;
                segments(*s)
            }
            Shape::Torus {
                major_radius,
                minor_radius,
                segments: s,
            } => {
                positive("torus major_radius", *major_radius)?;
                positive("torus minor_radius", *minor_radius)?;
                segments(*s)
            }
            Shape::Mesh {
                positions,
                indices,
                normals,
            } => {
                if indices.is_empty() {
                    return Err(Error::invalid("mesh has no triangles".to_string()));
                }
                for p in positions {
                    finite3("mesh position", *p)?;
                }
                if let Some(n) = normals {
                    if n.len() != positions.len() {
                        return Err(Error::invalid(format!(
                            "mesh has {} normals for {} positions",
                            n.len(),
                            positions.len()
                        )));
                    }
                    for v in n {
                        finite3("mesh normal", *v)?;
                    }
                }
                for (i, tri) in indices.iter().enumerate() {
                    if let Some(bad) = tri.iter().find(|k| **k as usize >= positions.len()) {
                        return Err(Error::invalid(format!(
                            "mesh triangle {i} refers to vertex {bad}, but there are only {}",
                            positions.len()
                        )));
                    }
                }
                Ok(())
            }
        }
    }
}

impl Material {
    fn validate(&self) -> Result<()> {
        colour("base_color", self.base_color)?;
        if self.base_color.iter().any(|c| *c > 1.0) {
            return Err(Error::invalid(format!(
                "base_color must be in [0, 1], got {:?}",
                self.base_color
            )));
        }
        for (name, v) in [
            ("metallic", self.metallic),
            ("roughness", self.roughness),
            ("specular", self.specular),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::invalid(format!("{name} must be in [0, 1], got {v}")));
            }
        }
        colour("emission", self.emission)?;
        if let Some(t) = &self.texture {
            positive("texture scale", t.scale)?;
            colour("texture color", t.color)?;
            if t.color.iter().any(|c| *c > 1.0) {
                return Err(Error::invalid(format!(
                    "texture color must be in [0, 1], got {:?}",
                    t.color
                )));
            }
            if !(0.0..=1.0).contains(&t.speckle) {
                return Err(Error::invalid(format!(
                    "texture speckle must be in [0, 1], got {}",
                    t.speckle
                )));
            }
            if let Pattern::Noise { octaves: Some(o) } = t.pattern {
                if !(1..=16).contains(&o) {
                    return Err(Error::invalid(format!(
                        "noise octaves must be in 1..=16, got {o}"
                    )));
                }
            }
        }
        Ok(())
    }
}

impl Light {
    fn validate(&self) -> Result<()> {
        match self {
            Light::Rect {
                center,
                edge_u,
                edge_v,
                radiance,
            } => {
                finite3("center", *center)?;
                finite3("edge_u", *edge_u)?;
                finite3("edge_v", *edge_v)?;
                colour("radiance", *radiance)?;
                let area = Vec3::from(*edge_u).cross(Vec3::from(*edge_v)).length();
                positive("rect area (|edge_u × edge_v|)", area)
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                finite3("center", *center)?;
                positive("radius", *radius)?;
                colour("radiance", *radiance)
            }
            Light::Directional {
                direction,
                irradiance,
                angular_diameter_deg,
            } => {
                finite3("direction", *direction)?;
                positive("direction length", Vec3::from(*direction).length())?;
                colour("irradiance", *irradiance)?;
                if !(0.0..90.0).contains(angular_diameter_deg) {
                    return Err(Error::invalid(format!(
                        "angular_diameter_deg must be in [0, 90), got {angular_diameter_deg}"
                    )));
                }
                Ok(())
            }
        }
    }
}

impl Environment {
    fn validate(&self) -> Result<()> {
        match self {
            Environment::Black => Ok(()),
            Environment::Constant { radiance } => colour("environment radiance", *radiance),
            Environment::Sky {
                zenith,
                horizon,
                ground,
            } => {
                colour("sky zenith", *zenith)?;
                colour("sky horizon", *horizon)?;
                colour("sky ground", *ground)
            }
            Environment::Equirect {
                scale,
                rotation_deg,
                ..
            } => {
                if !(scale.is_finite() && *scale >= 0.0) {
                    return Err(Error::invalid(format!(
                        "environment scale must be finite and >= 0, got {scale}"
                    )));
                }
                if !rotation_deg.is_finite() {
                    return Err(Error::invalid(format!(
                        "environment rotation_deg must be finite, got {rotation_deg}"
                    )));
                }
                Ok(())
            }
        }
    }
}
