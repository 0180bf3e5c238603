//! GPU copies of what a render reads: material textures and uniforms, the prefiltered
//! environment, the DFG table and the photo's shadow mask.

use std::collections::HashMap;
use std::sync::Arc;

use wgpu::util::DeviceExt;

use super::gpu_types::MaterialU;
use super::options::SpecularEnvironment;
use super::pipelines::Pipelines;
use crate::artefact::{AlphaMode, Artefact, Filter, Material, Sampler, TextureRef, Wrap};
use crate::error::{Error, Result};
use crate::image::Raster;

/// Creates a 2D texture with one mip level and fills it.
pub(crate) fn texture_2d(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    bytes: &[u8],
) -> wgpu::Texture {
    let texel = format.block_copy_size(None).unwrap_or(4);
    device.create_texture_with_data(
        queue,
        &wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        &bytes[..(width * height * texel) as usize],
    )
}

fn wrap(w: Wrap) -> wgpu::AddressMode {
    match w {
        Wrap::Repeat => wgpu::AddressMode::Repeat,
        Wrap::MirroredRepeat => wgpu::AddressMode::MirrorRepeat,
        Wrap::ClampToEdge => wgpu::AddressMode::ClampToEdge,
    }
}

fn filter(f: Filter) -> wgpu::FilterMode {
    match f {
        Filter::Nearest => wgpu::FilterMode::Nearest,
        Filter::Linear => wgpu::FilterMode::Linear,
    }
}

fn sampler(device: &wgpu::Device, s: &Sampler) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("parallax material sampler"),
        address_mode_u: wrap(s.wrap_u),
        address_mode_v: wrap(s.wrap_v),
        mag_filter: filter(s.mag_filter),
        min_filter: filter(s.min_filter),
        ..Default::default()
    })
}

/// The material bind groups of one render, keyed by (asset pointer, material index).
pub(crate) struct Materials {
    pub groups: HashMap<(usize, usize), wgpu::BindGroup>,
    pub default: wgpu::BindGroup,
    pub texture_count: usize,
}

struct Defaults {
    white: wgpu::TextureView,
    flat_normal: wgpu::TextureView,
    sampler: wgpu::Sampler,
}

/// Halves an RGBA8 image (box filter) until it fits `max` on both sides.
fn fit_rgba8(width: u32, height: u32, rgba: &[u8], max: u32) -> (u32, u32, Vec<u8>) {
    let (mut w, mut h, mut data) = (width, height, rgba.to_vec());
    while w > max || h > max {
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let mut out = vec![0u8; (nw * nh * 4) as usize];
        for y in 0..nh {
            for x in 0..nw {
                for c in 0..4 {
                    let mut sum = 0u32;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let sx = (2 * x + dx).min(w - 1);
                        let sy = (2 * y + dy).min(h - 1);
                        sum += data[((sy * w + sx) * 4 + c) as usize] as u32;
                    }
                    out[((y * nw + x) * 4 + c) as usize] = (sum / 4) as u8;
                }
            }
        }
        (w, h, data) = (nw, nh, out);
    }
    (w, h, data)
}

impl Materials {
    pub fn build(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pipelines: &Pipelines,
        assets: &HashMap<usize, Arc<Artefact>>,
        wanted: impl Iterator<Item = (usize, usize)>,
    ) -> Result<Materials> {
        let defaults = Defaults {
            white: texture_2d(
                device,
                queue,
                "white",
                (1, 1),
                wgpu::TextureFormat::Rgba8Unorm,
                &[255; 4],
            )
            .create_view(&Default::default()),
            flat_normal: texture_2d(
                device,
                queue,
                "flat normal",
                (1, 1),
                wgpu::TextureFormat::Rgba8Unorm,
                &[128, 128, 255, 255],
            )
            .create_view(&Default::default()),
            sampler: device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("parallax default sampler"),
                ..Default::default()
            }),
        };
        let max_size = device.limits().max_texture_dimension_2d;
        let mut textures: HashMap<(usize, bool), wgpu::TextureView> = HashMap::new();
        let mut groups = HashMap::new();
        for key in wanted {
            if groups.contains_key(&key) {
                continue;
            }
            let asset = assets.get(&key.0).ok_or_else(|| {
                Error::Internal(format!("material of unknown asset {:#x}", key.0))
            })?;
            let material = asset.materials.get(key.1).ok_or_else(|| {
                Error::Internal(format!("{}: material {} out of range", asset.source, key.1))
            })?;
            let mut slot = |r: Option<TextureRef>,
                            srgb: bool|
             -> Option<(wgpu::TextureView, wgpu::Sampler)> {
                let r = r?;
                let tex = asset.textures.get(r.texture)?;
                let image_key = (Arc::as_ptr(&tex.image) as usize, srgb);
                let view = textures
                    .entry(image_key)
                    .or_insert_with(|| {
                        let img = &tex.image;
                        let (w, h, data) =
                            fit_rgba8(img.width.max(1), img.height.max(1), &img.rgba8, max_size);
                        let format = if srgb {
                            wgpu::TextureFormat::Rgba8UnormSrgb
                        } else {
                            wgpu::TextureFormat::Rgba8Unorm
                        };
                        if data.len() < (w * h * 4) as usize {
                            // A malformed image (fewer bytes than its size) reads as white.
                            return defaults.white.clone();
                        }
                        texture_2d(device, queue, &img.name, (w, h), format, &data)
                            .create_view(&Default::default())
                    })
                    .clone();
                Some((view, sampler(device, &tex.sampler)))
            };
            let base = slot(material.base_color_texture, true);
            let mr = slot(material.metallic_roughness_texture, false);
            let normal = slot(material.normal_texture, false);
            let occlusion = slot(material.occlusion_texture, false);
            let emissive = slot(material.emissive_texture, true);
            let group = material_group(
                device,
                pipelines,
                &defaults,
                material,
                [base, mr, normal, occlusion, emissive],
            );
            groups.insert(key, group);
        }
        let default = material_group(
            device,
            pipelines,
            &defaults,
            &Material {
                metallic_factor: 0.0,
                ..Material::default()
            },
            [None, None, None, None, None],
        );
        Ok(Materials {
            groups,
            default,
            texture_count: textures.len(),
        })
    }
}

fn transform_rows(r: Option<TextureRef>) -> [[f32; 4]; 2] {
    match r.and_then(|r| r.transform) {
        Some(t) => {
            let m = t.matrix();
            // Rows of the 2×3 affine part: (m00 m01 m02), (m10 m11 m12) in column-major glam.
            [
                [m.x_axis.x, m.y_axis.x, m.z_axis.x, 0.0],
                [m.x_axis.y, m.y_axis.y, m.z_axis.y, 0.0],
            ]
        }
        None => [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]],
    }
}

fn material_group(
    device: &wgpu::Device,
    pipelines: &Pipelines,
    defaults: &Defaults,
    m: &Material,
    slots: [Option<(wgpu::TextureView, wgpu::Sampler)>; 5],
) -> wgpu::BindGroup {
    let refs = [
        m.base_color_texture,
        m.metallic_roughness_texture,
        m.normal_texture,
        m.occlusion_texture,
        m.emissive_texture,
    ];
    let mut xf = [[0.0f32; 4]; 10];
    for (i, r) in refs.iter().enumerate() {
        let rows = transform_rows(*r);
        xf[2 * i] = rows[0];
        xf[2 * i + 1] = rows[1];
    }
    let set = |r: Option<TextureRef>| r.map(|r| r.tex_coord.min(1)).unwrap_or(0);
    let (mode, cutoff) = match m.alpha_mode {
        AlphaMode::Opaque => (0.0, 0.0),
        AlphaMode::Mask { cutoff } => (1.0, cutoff),
        AlphaMode::Blend => (2.0, 0.0),
    };
    let emissive = m.emissive_factor * m.emissive_strength;
    let uniform = MaterialU {
        base_color: m.base_color_factor.to_array(),
        emissive: [emissive.x, emissive.y, emissive.z, 0.0],
        params: [
            m.metallic_factor,
            m.roughness_factor,
            m.normal_scale,
            m.occlusion_strength,
        ],
        alpha: [
            mode,
            cutoff,
            if slots[2].is_some() { 1.0 } else { 0.0 },
            0.0,
        ],
        uv_set: [set(refs[0]), set(refs[1]), set(refs[2]), set(refs[3])],
        uv_set2: [set(refs[4]), 0, 0, 0],
        xf,
    };
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("parallax material"),
        contents: bytemuck::bytes_of(&uniform),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let views: Vec<(wgpu::TextureView, wgpu::Sampler)> = slots
        .into_iter()
        .enumerate()
        .map(|(i, s)| {
            s.unwrap_or_else(|| {
                let view = if i == 2 {
                    defaults.flat_normal.clone()
                } else {
                    defaults.white.clone()
                };
                (view, defaults.sampler.clone())
            })
        })
        .collect();
    let mut entries = vec![wgpu::BindGroupEntry {
        binding: 0,
        resource: buffer.as_entire_binding(),
    }];
    for (i, (view, _)) in views.iter().enumerate() {
        entries.push(wgpu::BindGroupEntry {
            binding: 1 + i as u32,
            resource: wgpu::BindingResource::TextureView(view),
        });
    }
    for (i, (_, s)) in views.iter().enumerate() {
        entries.push(wgpu::BindGroupEntry {
            binding: 6 + i as u32,
            resource: wgpu::BindingResource::Sampler(s),
        });
    }
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("parallax material"),
        layout: &pipelines.material_layout,
        entries: &entries,
    })
}

fn f16_bytes(values: impl Iterator<Item = f32>) -> Vec<u8> {
    let halves: Vec<half::f16> = values
        .map(|v| half::f16::from_f32(v.clamp(0.0, 65000.0)))
        .collect();
    bytemuck::cast_slice(&halves).to_vec()
}

/// The prefiltered cube (Rgba16Float, filterable on every device) and the DFG table.
pub(crate) fn upload_environment(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    env: &SpecularEnvironment<'_>,
) -> Result<(wgpu::TextureView, wgpu::TextureView, u32)> {
    let levels = &env.prefiltered.levels;
    let base = levels
        .first()
        .ok_or_else(|| Error::invalid("specular environment: the cube map has no level"))?
        .size;
    if base == 0 || base > device.limits().max_texture_dimension_2d {
        return Err(Error::invalid(format!(
            "specular environment: cube face size {base} must be in [1, {}]",
            device.limits().max_texture_dimension_2d
        )));
    }
    let max_levels = 32 - base.leading_zeros();
    if levels.len() as u32 > max_levels {
        return Err(Error::invalid(format!(
            "specular environment: {} mip levels for a {base}-texel face (at most {max_levels})",
            levels.len()
        )));
    }
    for (k, level) in levels.iter().enumerate() {
        let expected = (base >> k).max(1);
        if level.size != expected {
            return Err(Error::invalid(format!(
                "specular environment: level {k} is {} texels, expected {expected}",
                level.size
            )));
        }
        let n = 6 * (level.size as usize).pow(2);
        if level.texels.len() != n {
            return Err(Error::SizeMismatch(format!(
                "specular environment: level {k} has {} texels, expected 6·{}² = {n}",
                level.texels.len(),
                level.size
            )));
        }
        if let Some(t) = level
            .texels
            .iter()
            .find(|t| !t.iter().all(|c| c.is_finite()))
        {
            return Err(Error::invalid(format!(
                "specular environment: level {k} holds a non-finite texel {t:?}"
            )));
        }
    }
    let mut data = Vec::new();
    for level in levels {
        data.extend(f16_bytes(
            level.texels.iter().flat_map(|t| [t[0], t[1], t[2], 1.0]),
        ));
    }
    let cube = device.create_texture_with_data(
        queue,
        &wgpu::TextureDescriptor {
            label: Some("parallax prefiltered environment"),
            size: wgpu::Extent3d {
                width: base,
                height: base,
                depth_or_array_layers: 6,
            },
            mip_level_count: levels.len() as u32,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        // Our data is mip-major (all faces of level 0, then level 1, …).
        wgpu::util::TextureDataOrder::MipMajor,
        &data,
    );
    let cube_view = cube.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::Cube),
        ..Default::default()
    });
    let n = env.dfg_size as usize;
    if n == 0 || env.dfg.len() != n * n {
        return Err(Error::SizeMismatch(format!(
            "specular environment: DFG table has {} entries, expected {n}² for dfg_size {n}",
            env.dfg.len()
        )));
    }
    if env.dfg.iter().any(|v| !v.iter().all(|c| c.is_finite())) {
        return Err(Error::invalid(
            "specular environment: DFG table holds a non-finite value",
        ));
    }
    let dfg = texture_2d(
        device,
        queue,
        "parallax DFG",
        (n as u32, n as u32),
        wgpu::TextureFormat::Rgba16Float,
        &f16_bytes(env.dfg.iter().flat_map(|v| [v[0], v[1], 0.0, 1.0])),
    );
    Ok((
        cube_view,
        dfg.create_view(&Default::default()),
        levels.len() as u32,
    ))
}

/// Stand-ins bound when there is no environment: a black 1×1 cube and a zero DFG texel.
pub(crate) fn empty_environment(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
) -> (wgpu::TextureView, wgpu::TextureView) {
    let cube = device.create_texture_with_data(
        queue,
        &wgpu::TextureDescriptor {
            label: Some("parallax empty environment"),
            size: wgpu::Extent3d {
                width: 1,
                height: 1,
                depth_or_array_layers: 6,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        &[0u8; 6 * 8],
    );
    let cube_view = cube.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::Cube),
        ..Default::default()
    });
    let dfg = texture_2d(
        device,
        queue,
        "parallax empty DFG",
        (1, 1),
        wgpu::TextureFormat::Rgba16Float,
        &[0u8; 8],
    );
    (cube_view, dfg.create_view(&Default::default()))
}

/// The photo's shadow mask as an R32Float texture (read with textureLoad, no filtering), or a
/// 1×1 zero stand-in.
pub(crate) fn mask_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    mask: Option<&Raster<f32>>,
) -> wgpu::TextureView {
    let (size, data): ((u32, u32), Vec<f32>) = match mask {
        Some(m) => (
            (m.width() as u32, m.height() as u32),
            m.pixels()
                .iter()
                .map(|v| {
                    if v.is_finite() {
                        v.clamp(0.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect(),
        ),
        None => ((1, 1), vec![0.0]),
    };
    texture_2d(
        device,
        queue,
        "parallax photo shadow mask",
        size,
        wgpu::TextureFormat::R32Float,
        bytemuck::cast_slice(&data),
    )
    .create_view(&Default::default())
}
