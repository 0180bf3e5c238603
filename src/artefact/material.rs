//! Materials (glTF 2.0 metallic-roughness) and their textures, decoded once and shared.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{Mat3, Vec2, Vec3, Vec4};

use super::buffers::Buffers;
use super::limits::{mul, LoadLimits, MemoryBudget};
use super::uri::{self, UriTarget};
use crate::error::{Error, Result};

/// How a material's alpha is used (glTF `alphaMode`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AlphaMode {
    /// Alpha ignored; the surface is fully opaque.
    Opaque,
    /// Fragments with alpha below `cutoff` are discarded, the rest are opaque.
    Mask {
        /// Alpha threshold in [0, 1] (glTF default 0.5).
        cutoff: f32,
    },
    /// Alpha-blended over what lies behind (the thesis' per-artefact translucency).
    Blend,
}

/// Texture coordinate wrapping along one axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wrap {
    /// Tiles (glTF default).
    Repeat,
    /// Tiles, mirrored every other tile.
    MirroredRepeat,
    /// Clamps to the edge texel.
    ClampToEdge,
}

/// Texel filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Filter {
    /// Nearest texel.
    Nearest,
    /// Bilinear.
    Linear,
}

/// Sampler settings of a texture (glTF `sampler`; unset filters default to linear).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sampler {
    /// Wrapping of u.
    pub wrap_u: Wrap,
    /// Wrapping of v.
    pub wrap_v: Wrap,
    /// Magnification filter.
    pub mag_filter: Filter,
    /// Minification filter within a mip level.
    pub min_filter: Filter,
    /// Filter between mip levels; `None` when the file asks for no mipmaps.
    pub mipmap_filter: Option<Filter>,
}

impl Default for Sampler {
    fn default() -> Self {
        Sampler {
            wrap_u: Wrap::Repeat,
            wrap_v: Wrap::Repeat,
            mag_filter: Filter::Linear,
            min_filter: Filter::Linear,
            mipmap_filter: Some(Filter::Linear),
        }
    }
}

/// Decoded pixels of one glTF image: 8-bit RGBA, rows top to bottom, packed.
///
/// The bytes are the file's code values: base-colour and emissive textures hold sRGB-encoded
/// colour, the other slots hold linear data (glTF spec §3.9.6).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TextureImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height × 4` bytes, RGBA.
    pub rgba8: Vec<u8>,
    /// The image's name or URI file name, for messages.
    pub name: String,
}

/// A texture: shared decoded pixels plus sampler settings. Two textures that use the same image
/// share one [`TextureImage`] (`Arc`).
#[derive(Debug, Clone)]
pub struct Texture {
    /// The decoded pixels.
    pub image: Arc<TextureImage>,
    /// Wrapping and filtering.
    pub sampler: Sampler,
}

/// `KHR_texture_transform`: uv' = T(offset) · R(rotation) · S(scale) · uv.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UvTransform {
    /// Translation in uv units.
    pub offset: Vec2,
    /// Rotation in radians (counter-clockwise as seen in uv space, per the extension).
    pub rotation: f32,
    /// Scale per axis.
    pub scale: Vec2,
}

impl UvTransform {
    /// The 3×3 matrix applied to (u, v, 1), as the extension defines it.
    pub fn matrix(&self) -> Mat3 {
        let (s, c) = self.rotation.sin_cos();
        let translation = Mat3::from_cols(Vec3::X, Vec3::Y, self.offset.extend(1.0));
        let rotation = Mat3::from_cols(Vec3::new(c, -s, 0.0), Vec3::new(s, c, 0.0), Vec3::Z);
        let scale = Mat3::from_diagonal(self.scale.extend(1.0));
        translation * rotation * scale
    }

    /// Applies the transform to one coordinate.
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        self.matrix().transform_point2(uv)
    }
}

/// A material's use of a texture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureRef {
    /// Index into [`super::Artefact::textures`].
    pub texture: usize,
    /// Which coordinate set the texture reads: 0 = `uv0`, 1 = `uv1` of the primitive.
    pub tex_coord: u32,
    /// `KHR_texture_transform`, if any.
    pub transform: Option<UvTransform>,
}

/// A glTF 2.0 metallic-roughness material. Colours are linear.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// The material's name in the file.
    pub name: Option<String>,
    /// Linear RGBA multiplier of the base colour (alpha = translucency when `Blend`).
    pub base_color_factor: Vec4,
    /// Base colour texture (sRGB RGB, linear alpha).
    pub base_color_texture: Option<TextureRef>,
    /// Metalness in [0, 1].
    pub metallic_factor: f32,
    /// Perceptual roughness in [0, 1].
    pub roughness_factor: f32,
    /// Roughness in G and metalness in B (linear).
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Tangent-space normal map (linear).
    pub normal_texture: Option<TextureRef>,
    /// Scale of the normal map's X and Y.
    pub normal_scale: f32,
    /// Ambient occlusion in R (linear).
    pub occlusion_texture: Option<TextureRef>,
    /// How much of the occlusion applies, in [0, 1].
    pub occlusion_strength: f32,
    /// Linear emitted radiance multiplier (relative to the photo's white).
    pub emissive_factor: Vec3,
    /// `KHR_materials_emissive_strength` (1 when absent), multiplies `emissive_factor`.
    pub emissive_strength: f32,
    /// Emissive texture (sRGB).
    pub emissive_texture: Option<TextureRef>,
    /// How alpha is used.
    pub alpha_mode: AlphaMode,
    /// Both faces are drawn and lit (back faces with the flipped normal).
    pub double_sided: bool,
}

impl Default for Material {
    /// The glTF default material (spec §3.9.6 and §5.19): white, fully metallic and rough.
    fn default() -> Self {
        Material {
            name: None,
            base_color_factor: Vec4::ONE,
            base_color_texture: None,
            metallic_factor: 1.0,
            roughness_factor: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            occlusion_texture: None,
            occlusion_strength: 1.0,
            emissive_factor: Vec3::ZERO,
            emissive_strength: 1.0,
            emissive_texture: None,
            alpha_mode: AlphaMode::Opaque,
            double_sided: false,
        }
    }
}

impl Material {
    /// Every texture slot that is set, with its name (for listings and UV-set checks).
    pub fn texture_slots(&self) -> Vec<(&'static str, TextureRef)> {
        [
            ("base colour", self.base_color_texture),
            ("metallic-roughness", self.metallic_roughness_texture),
            ("normal", self.normal_texture),
            ("occlusion", self.occlusion_texture),
            ("emissive", self.emissive_texture),
        ]
        .into_iter()
        .filter_map(|(n, t)| t.map(|t| (n, t)))
        .collect()
    }

    /// This material with every texture that reads coordinate set `set` removed.
    pub(crate) fn without_tex_coord(&self, set: u32) -> Material {
        let keep = |t: Option<TextureRef>| t.filter(|t| t.tex_coord != set);
        Material {
            base_color_texture: keep(self.base_color_texture),
            metallic_roughness_texture: keep(self.metallic_roughness_texture),
            normal_texture: keep(self.normal_texture),
            occlusion_texture: keep(self.occlusion_texture),
            emissive_texture: keep(self.emissive_texture),
            ..self.clone()
        }
    }
}

/// Turns glTF materials into [`Material`]s, decoding each image the first time a material uses
/// it.
pub(crate) struct MaterialBuilder<'a> {
    doc: &'a gltf::Document,
    pub(crate) buffers: &'a Buffers,
    pub(crate) base: Option<&'a Path>,
    pub(crate) limits: &'a LoadLimits,
    /// glTF texture index → index in `textures`.
    texture_map: HashMap<usize, usize>,
    /// glTF image index → decoded pixels.
    images: HashMap<usize, Arc<TextureImage>>,
    pub(crate) textures: Vec<Texture>,
}

impl<'a> MaterialBuilder<'a> {
    pub(crate) fn new(
        doc: &'a gltf::Document,
        buffers: &'a Buffers,
        base: Option<&'a Path>,
        limits: &'a LoadLimits,
    ) -> Self {
        MaterialBuilder {
            doc,
            buffers,
            base,
            limits,
            texture_map: HashMap::new(),
            images: HashMap::new(),
            textures: Vec::new(),
        }
    }

    /// Converts material `m`, clamping out-of-range factors with a warning.
    ///
    /// # Errors
    /// Texture decoding errors (`Format`, `TooLarge`, `Unsupported`, `Io`, URI policy) naming
    /// the material, texture and image.
    pub(crate) fn convert(
        &mut self,
        m: &gltf::Material,
        warnings: &mut Vec<String>,
        budget: &mut MemoryBudget,
    ) -> Result<Material> {
        let label = match (m.index(), m.name()) {
            (Some(i), Some(n)) => format!("material {i} ('{n}')"),
            (Some(i), None) => format!("material {i}"),
            _ => "default material".to_string(),
        };
        let mut clamp01 = |v: f32, default: f32, field: &str| -> f32 {
            if !v.is_finite() {
                warnings.push(format!(
                    "{label}: {field} {v} is not finite; using {default}"
                ));
                default
            } else if !(0.0..=1.0).contains(&v) {
                let c = v.clamp(0.0, 1.0);
                warnings.push(format!("{label}: {field} {v} is outside [0, 1]; using {c}"));
                c
            } else {
                v
            }
        };
        let pbr = m.pbr_metallic_roughness();
        let bc = pbr.base_color_factor();
        let base_color_factor = Vec4::new(
            clamp01(bc[0], 1.0, "baseColorFactor[0]"),
            clamp01(bc[1], 1.0, "baseColorFactor[1]"),
            clamp01(bc[2], 1.0, "baseColorFactor[2]"),
            clamp01(bc[3], 1.0, "baseColorFactor[3]"),
        );
        let metallic_factor = clamp01(pbr.metallic_factor(), 1.0, "metallicFactor");
        let roughness_factor = clamp01(pbr.roughness_factor(), 1.0, "roughnessFactor");
        let ef = m.emissive_factor();
        let emissive_factor = Vec3::new(
            clamp01(ef[0], 0.0, "emissiveFactor[0]"),
            clamp01(ef[1], 0.0, "emissiveFactor[1]"),
            clamp01(ef[2], 0.0, "emissiveFactor[2]"),
        );
        let occlusion_strength = m.occlusion_texture().map_or(1.0, |o| {
            clamp01(o.strength(), 1.0, "occlusionTexture.strength")
        });
        let alpha_mode = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            gltf::material::AlphaMode::Mask => AlphaMode::Mask {
                cutoff: clamp01(m.alpha_cutoff().unwrap_or(0.5), 0.5, "alphaCutoff"),
            },
        };
        let emissive_strength = match m.emissive_strength() {
            Some(s) if s.is_finite() && s >= 0.0 => s,
            Some(s) => {
                warnings.push(format!(
                    "{label}: KHR_materials_emissive_strength {s} is not a finite value ≥ 0; using 1"
                ));
                1.0
            }
            None => 1.0,
        };
        let normal_scale = m.normal_texture().map_or(1.0, |n| n.scale());
        let normal_scale = if normal_scale.is_finite() {
            normal_scale
        } else {
            warnings.push(format!(
                "{label}: normalTexture.scale is not finite; using 1"
            ));
            1.0
        };

        let base_color_texture = match pbr.base_color_texture() {
            Some(info) => {
                Some(self.info_ref(&info, &label, "baseColorTexture", warnings, budget)?)
            }
            None => None,
        };
        let metallic_roughness_texture = match pbr.metallic_roughness_texture() {
            Some(info) => {
                Some(self.info_ref(&info, &label, "metallicRoughnessTexture", warnings, budget)?)
            }
            None => None,
        };
        let emissive_texture = match m.emissive_texture() {
            Some(info) => {
                Some(self.info_ref(&info, &label, "emissiveTexture", warnings, budget)?)
            }
            None => None,
        };
        let normal_texture = match m.normal_texture() {
            Some(n) => {
                let what = format!("{label} normalTexture");
                let transform = transform_from_value(
                    n.extension_value("KHR_texture_transform"),
                    &what,
                    warnings,
                )?;
                Some(self.texture_ref(&n.texture(), n.tex_coord(), transform, &what, budget)?)
            }
            None => None,
        };
        let occlusion_texture = match m.occlusion_texture() {
            Some(o) => {
                let what = format!("{label} occlusionTexture");
                let transform = transform_from_value(
                    o.extension_value("KHR_texture_transform"),
                    &what,
                    warnings,
                )?;
                Some(self.texture_ref(&o.texture(), o.tex_coord(), transform, &what, budget)?)
            }
            None => None,
        };
        Ok(Material {
            name: m.name().map(str::to_string),
            base_color_factor,
            base_color_texture,
            metallic_factor,
            roughness_factor,
            metallic_roughness_texture,
            normal_texture,
            normal_scale,
            occlusion_texture,
            occlusion_strength,
            emissive_factor,
            emissive_strength,
            emissive_texture,
            alpha_mode,
            double_sided: m.double_sided(),
        })
    }

    fn info_ref(
        &mut self,
        info: &gltf::texture::Info,
        label: &str,
        slot: &str,
        warnings: &mut Vec<String>,
        budget: &mut MemoryBudget,
    ) -> Result<TextureRef> {
        let what = format!("{label} {slot}");
        let transform = info.texture_transform().map(|t| UvTransform {
            offset: Vec2::from(t.offset()),
            rotation: t.rotation(),
            scale: Vec2::from(t.scale()),
        });
        let transform = match transform {
            Some(t) => check_transform(t, &what, warnings),
            None => None,
        };
        let tex_coord = info
            .texture_transform()
            .and_then(|t| t.tex_coord())
            .unwrap_or(info.tex_coord());
        self.texture_ref(&info.texture(), tex_coord, transform, &what, budget)
    }

    fn texture_ref(
        &mut self,
        texture: &gltf::Texture,
        tex_coord: u32,
        transform: Option<UvTransform>,
        what: &str,
        budget: &mut MemoryBudget,
    ) -> Result<TextureRef> {
        let index = match self.texture_map.get(&texture.index()) {
            Some(&i) => i,
            None => {
                let image = texture.source();
                let pixels = match self.images.get(&image.index()) {
                    Some(p) => p.clone(),
                    None => {
                        let p = Arc::new(self.decode_image(&image, what, budget)?);
                        self.images.insert(image.index(), p.clone());
                        p
                    }
                };
                let s = texture.sampler();
                let wrap = |w| match w {
                    gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
                    gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
                    gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
                };
                use gltf::texture::MinFilter as M;
                let (min_filter, mipmap_filter) = match s.min_filter() {
                    None => (Filter::Linear, Some(Filter::Linear)),
                    Some(M::Nearest) => (Filter::Nearest, None),
                    Some(M::Linear) => (Filter::Linear, None),
                    Some(M::NearestMipmapNearest) => (Filter::Nearest, Some(Filter::Nearest)),
                    Some(M::LinearMipmapNearest) => (Filter::Linear, Some(Filter::Nearest)),
                    Some(M::NearestMipmapLinear) => (Filter::Nearest, Some(Filter::Linear)),
                    Some(M::LinearMipmapLinear) => (Filter::Linear, Some(Filter::Linear)),
                };
                let sampler = Sampler {
                    wrap_u: wrap(s.wrap_s()),
                    wrap_v: wrap(s.wrap_t()),
                    mag_filter: match s.mag_filter() {
                        Some(gltf::texture::MagFilter::Nearest) => Filter::Nearest,
                        _ => Filter::Linear,
                    },
                    min_filter,
                    mipmap_filter,
                };
                self.textures.push(Texture {
                    image: pixels,
                    sampler,
                });
                let i = self.textures.len() - 1;
                self.texture_map.insert(texture.index(), i);
                i
            }
        };
        Ok(TextureRef {
            texture: index,
            tex_coord,
            transform,
        })
    }

    fn decode_image(
        &self,
        image: &gltf::Image,
        what: &str,
        budget: &mut MemoryBudget,
    ) -> Result<TextureImage> {
        let what = format!("{what}: image {}", image.index());
        // Read from the JSON: the `gltf` crate's `Image::source` unwraps a missing mimeType.
        let json = self
            .doc
            .as_json()
            .images
            .get(image.index())
            .ok_or_else(|| Error::format(format!("{what} does not exist")))?;
        let (bytes, name): (std::borrow::Cow<[u8]>, String) = match (&json.buffer_view, &json.uri) {
            (Some(view_index), _) => {
                let view = self.doc.views().nth(view_index.value()).ok_or_else(|| {
                    Error::format(format!(
                        "{what} refers to bufferView {}, which does not exist",
                        view_index.value()
                    ))
                })?;
                (
                    self.buffers.view_bytes(&view)?.into(),
                    image
                        .name()
                        .map_or_else(|| format!("bufferView {}", view.index()), str::to_string),
                )
            }
            (None, Some(u)) => {
                let name = if u.starts_with("data:") {
                    image.name().unwrap_or("data URI").to_string()
                } else {
                    u.to_string()
                };
                let bytes = match uri::resolve(u, self.base, &what, budget)? {
                    UriTarget::Data(b) => b,
                    UriTarget::File(path) => {
                        let base = self.base.ok_or_else(|| {
                            Error::Internal(format!("{what}: file URI without a base folder"))
                        })?;
                        uri::read_file(&path, base, &what, budget)?
                    }
                };
                (bytes.into(), name)
            }
            (None, None) => {
                return Err(Error::format(format!(
                    "{what} has neither a uri nor a bufferView"
                )))
            }
        };
        let what = format!("{what} ('{name}')");
        decode_rgba8(&bytes, self.limits, &what, budget).map(|(width, height, rgba8)| {
            TextureImage {
                width,
                height,
                rgba8,
                name,
            }
        })
    }
}

/// Decodes PNG or JPEG bytes to RGBA8, checking the size against the caps before decoding.
pub(crate) fn decode_rgba8(
    bytes: &[u8],
    limits: &LoadLimits,
    what: &str,
    budget: &mut MemoryBudget,
) -> Result<(u32, u32, Vec<u8>)> {
    let format = match bytes {
        [0x89, b'P', b'N', b'G', ..] => image::ImageFormat::Png,
        [0xFF, 0xD8, 0xFF, ..] => image::ImageFormat::Jpeg,
        _ => {
            return Err(Error::Unsupported(format!(
                "{what} is neither PNG nor JPEG (the formats glTF 2.0 allows without extensions)"
            )))
        }
    };
    let reader = |bytes| {
        let mut r = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
        let mut l = image::Limits::default();
        let side = limits.max_texture_side;
        l.max_image_width = Some(side);
        l.max_image_height = Some(side);
        // Decoders hold at most the 16-bit RGBA image plus the RGBA8 copy.
        l.max_alloc = Some((side as u64 * side as u64 * 12).max(1 << 20));
        r.limits(l);
        r
    };
    let (w, h) = reader(bytes)
        .into_dimensions()
        .map_err(|e| Error::format(format!("{what}: {e}")))?;
    if w == 0 || h == 0 || w > limits.max_texture_side || h > limits.max_texture_side {
        return Err(Error::TooLarge(format!(
            "{what} is {w}x{h}; textures must be between 1 and {} pixels on a side \
             (LoadLimits::max_texture_side)",
            limits.max_texture_side
        )));
    }
    budget.reserve(what, mul(w as u64 * h as u64, 4, what)?)?;
    let decoded = reader(bytes)
        .decode()
        .map_err(|e| Error::format(format!("{what}: {e}")))?;
    Ok((w, h, decoded.to_rgba8().into_raw()))
}

/// A transform with every value finite, or `None` with a warning.
fn check_transform(t: UvTransform, what: &str, warnings: &mut Vec<String>) -> Option<UvTransform> {
    let finite = t.offset.is_finite() && t.rotation.is_finite() && t.scale.is_finite();
    if finite {
        Some(t)
    } else {
        warnings.push(format!(
            "{what}: KHR_texture_transform has a non-finite value; transform ignored"
        ));
        None
    }
}

/// `KHR_texture_transform` from raw JSON (the slots the `gltf` crate does not type).
fn transform_from_value(
    value: Option<&serde_json::Value>,
    what: &str,
    warnings: &mut Vec<String>,
) -> Result<Option<UvTransform>> {
    let Some(v) = value else { return Ok(None) };
    let bad = |field: &str| {
        Error::format(format!(
            "{what}: KHR_texture_transform.{field} has the wrong type"
        ))
    };
    let obj = v.as_object().ok_or_else(|| bad("(object)"))?;
    let pair = |field: &str, default: [f32; 2]| -> Result<Vec2> {
        match obj.get(field) {
            None => Ok(Vec2::from(default)),
            Some(serde_json::Value::Array(a)) if a.len() == 2 => {
                let x = a[0].as_f64().ok_or_else(|| bad(field))?;
                let y = a[1].as_f64().ok_or_else(|| bad(field))?;
                Ok(Vec2::new(x as f32, y as f32))
            }
            Some(_) => Err(bad(field)),
        }
    };
    let rotation = match obj.get("rotation") {
        None => 0.0,
        Some(r) => r.as_f64().ok_or_else(|| bad("rotation"))? as f32,
    };
    let t = UvTransform {
        offset: pair("offset", [0.0, 0.0])?,
        rotation,
        scale: pair("scale", [1.0, 1.0])?,
    };
    if obj.contains_key("texCoord") {
        warnings.push(format!(
            "{what}: KHR_texture_transform.texCoord on this slot is ignored"
        ));
    }
    Ok(check_transform(t, what, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uv_transform_follows_the_extension_definition() {
        let t = UvTransform {
            offset: Vec2::new(0.5, 0.25),
            rotation: std::f32::consts::FRAC_PI_2,
            scale: Vec2::new(2.0, 3.0),
        };
        // S: (1, 0) → (2, 0); R(π/2) with the extension's matrix: (u, v) → (v, −u) → (0, −2);
        // T: + (0.5, 0.25).
        let p = t.apply(Vec2::new(1.0, 0.0));
        assert!((p - Vec2::new(0.5, -1.75)).length() < 1e-6, "{p}");
        let id = UvTransform {
            offset: Vec2::ZERO,
            rotation: 0.0,
            scale: Vec2::ONE,
        };
        assert_eq!(id.apply(Vec2::new(0.3, 0.7)), Vec2::new(0.3, 0.7));
    }

    #[test]
    fn transform_from_json_checks_types() {
        let mut w = Vec::new();
        let v = serde_json::json!({"offset": [0.5, 0.0], "rotation": 1.0, "scale": [2.0, 2.0]});
        let t = transform_from_value(Some(&v), "m", &mut w)
            .unwrap()
            .unwrap();
        assert_eq!(t.offset, Vec2::new(0.5, 0.0));
        assert_eq!(t.rotation, 1.0);
        let bad = serde_json::json!({"offset": "x"});
        let e = transform_from_value(Some(&bad), "material 2 normalTexture", &mut w).unwrap_err();
        assert!(e.to_string().contains("material 2 normalTexture"), "{e}");
        assert!(transform_from_value(Some(&serde_json::json!(3)), "m", &mut w).is_err());
    }

    #[test]
    fn decode_refuses_oversize_before_decoding_and_non_png_jpeg() {
        // A valid 4x2 PNG, decoded, then refused under a 3-pixel side cap.
        let mut png = Vec::new();
        image::RgbaImage::from_pixel(4, 2, image::Rgba([10, 20, 30, 40]))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let limits = LoadLimits::default();
        let mut b = MemoryBudget::new(&limits);
        let (w, h, px) = decode_rgba8(&png, &limits, "t", &mut b).unwrap();
        assert_eq!((w, h), (4, 2));
        assert_eq!(&px[..4], &[10, 20, 30, 40]);
        let small = LoadLimits {
            max_texture_side: 3,
            ..limits
        };
        let e = decode_rgba8(&png, &small, "image 7", &mut b).unwrap_err();
        assert!(matches!(e, Error::TooLarge(_) | Error::Format(_)), "{e}");
        assert!(e.to_string().contains("image 7"), "{e}");
        let e = decode_rgba8(b"GIF89a....", &limits, "image 8", &mut b).unwrap_err();
        assert!(matches!(e, Error::Unsupported(_)), "{e}");
        let e = decode_rgba8(&png[..30], &limits, "image 9", &mut b).unwrap_err();
        assert!(matches!(e, Error::Format(_)), "{e}");
    }
}
