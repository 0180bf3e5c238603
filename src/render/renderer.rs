//! [`Renderer`]: shadow maps → artefacts (MSAA, occluded by the scene mesh) → shadow ratio on
//! the scene mesh → composite `photo × ratio + artefacts`.

use std::time::Instant;

use glam::Mat4;
use wgpu::util::DeviceExt;

use super::context::{read_texture, GpuContext};
use super::geometry::{corners, SceneGeometry};
use super::gpu_types::{FrameU, LightU, ShadowPassU, ViewU};
use super::options::{
    Composite, RenderInputs, RenderOptions, RenderRecord, ShadingMode, ShadowMode,
    EVSM_EXPONENT_LIMIT,
};
use super::pipelines::{DrawKind, Pipelines, TargetFormats, DEPTH_FORMAT, LAYER_FORMAT};
use super::resources::{empty_environment, mask_texture, upload_environment, Materials};
use super::shadow_views::{plan, LightShadowPlan, ShadowView};
use crate::camera::DepthEncoding;
use crate::error::{Error, Result};
use crate::image::Raster;
use crate::light::LightKind;

/// Most memory all shadow maps of one render may take; larger requests get smaller maps.
pub const SHADOW_MEMORY_BUDGET: u64 = 256 << 20;

/// The layer count to create the shadow-map texture with, for `used` layers, on `backend`.
///
/// wgpu's OpenGL backend creates each texture with one GL target, and guesses it from the
/// descriptor, since a view cannot change it later (wgpu-hal `gles`,
/// `Texture::get_info_from_desc`): a 2D texture of one layer becomes a plain 2D texture, and a
/// square one whose layer count is a multiple of 6 a cube map (or cube-map array). Our 2D-array
/// view of either does not read the maps we rendered, so shadows came out wrong on OpenGL for
/// one layer (one light, and only the artefacts or only the scene mesh casting) and for 6·k (a
/// point light's cube of six views, three lights of two layers each). There the texture gets
/// one unused layer more, which keeps it a 2D array; other backends get exactly `used` (an
/// empty texture still needs one layer).
fn shadow_texture_layers(used: u32, backend: wgpu::Backend) -> u32 {
    let gl = backend == wgpu::Backend::Gl;
    if gl && (used <= 1 || used.is_multiple_of(6)) {
        used.max(1) + 1
    } else {
        used.max(1)
    }
}

/// What a wgpu error says, on one line: its description (for validation and internal errors,
/// whose `Display` is only "Validation Error" or "Internal error"), else its `Display` and the
/// chain of its sources.
fn wgpu_error_text(e: &wgpu::Error) -> String {
    match e {
        wgpu::Error::Validation { description, .. } | wgpu::Error::Internal { description, .. } => {
            description.split_whitespace().collect::<Vec<_>>().join(" ")
        }
        other => {
            let mut text = other.to_string();
            let mut source = std::error::Error::source(other);
            while let Some(s) = source {
                text.push_str(&format!(": {s}"));
                source = s.source();
            }
            text
        }
    }
}

/// The real-time renderer: pipelines compiled once, reused for every render on its device.
///
/// Thread safety: `render` takes `&self`; wgpu devices and queues are shareable, so one renderer
/// may serve several threads (their submissions are serialised by the queue).
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipelines: Pipelines,
    /// The device's backend: wgpu's OpenGL backend needs the shadow maps' layer count adjusted
    /// ([`shadow_texture_layers`]).
    backend: wgpu::Backend,
}

impl std::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Renderer").finish_non_exhaustive()
    }
}

struct Timer {
    records: Vec<RenderRecord>,
}

impl Timer {
    fn ran(&mut self, stage: &str, start: Instant, why: impl Into<String>) {
        self.records.push(RenderRecord {
            stage: stage.into(),
            computed: true,
            ms: start.elapsed().as_secs_f64() * 1e3,
            why: why.into(),
        });
    }
    fn skipped(&mut self, stage: &str, why: impl Into<String>) {
        self.records.push(RenderRecord {
            stage: stage.into(),
            computed: false,
            ms: 0.0,
            why: why.into(),
        });
    }
}

fn mat(m: Mat4) -> [[f32; 4]; 4] {
    m.to_cols_array_2d()
}

fn target(
    device: &wgpu::Device,
    label: &str,
    (w, h): (u32, u32),
    format: wgpu::TextureFormat,
    samples: u32,
    readable: bool,
) -> wgpu::Texture {
    let mut usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
    if readable {
        usage |= wgpu::TextureUsages::COPY_SRC;
    }
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: samples,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

/// The texels of a read-back float texture (`R32Float`/`Rgba32Float` or their 16-bit
/// counterparts) as `f32`, channels interleaved.
fn float_texels(bytes: &[u8], format: wgpu::TextureFormat) -> Vec<f32> {
    match format {
        wgpu::TextureFormat::R16Float | wgpu::TextureFormat::Rgba16Float => bytes
            .chunks_exact(2)
            .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
            .collect(),
        _ => bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
    }
}

impl Renderer {
    /// A renderer on the library's own GPU context.
    ///
    /// # Errors
    /// As [`Renderer::from_device`].
    pub fn new(gpu: &GpuContext) -> Result<Renderer> {
        Renderer::from_device(&gpu.device, &gpu.queue)
    }

    /// A renderer on a host's device and queue (Rust callers that already run wgpu). The device
    /// needs no optional feature: every 32-bit float texture is read without filtering, and 4×
    /// MSAA of `Rgba16Float` and `Depth32Float` is guaranteed by WebGPU. Where the device cannot
    /// render into 32-bit float textures (wgpu's OpenGL backend on some drivers, Mesa's llvmpipe
    /// among them), shadow maps, the shadow ratio and the artefacts' depth are 16-bit floats
    /// instead (see `TargetFormats::FLOAT16`), and the `render.gpu` record says so.
    ///
    /// # Errors
    /// `Gpu` when the device rejects a shader or pipeline with both sets of formats (the message
    /// has wgpu's reason for each).
    pub fn from_device(device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Renderer> {
        let reason = |e: Error| match e {
            Error::Gpu(message) => message,
            other => other.to_string(),
        };
        Renderer::with_formats(device, queue, TargetFormats::FLOAT32).or_else(|full| {
            Renderer::with_formats(device, queue, TargetFormats::FLOAT16).map_err(|reduced| {
                Error::Gpu(format!(
                    "{}; with 16-bit float targets instead: {}",
                    reason(full),
                    reason(reduced)
                ))
            })
        })
    }

    /// A renderer whose shadow maps, shadow ratio and artefact depth have `formats`.
    ///
    /// # Errors
    /// `Gpu` when the device rejects a shader or pipeline (the message has wgpu's reason).
    pub(crate) fn with_formats(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        formats: TargetFormats,
    ) -> Result<Renderer> {
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipelines = Pipelines::new(device, formats);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu(format!(
                "creating the render pipelines failed: {}",
                wgpu_error_text(&e)
            )));
        }
        Ok(Renderer {
            device: device.clone(),
            queue: queue.clone(),
            pipelines,
            backend: device.adapter_info().backend,
        })
    }

    /// Renders the artefacts into the photo. See the module documentation for the passes.
    ///
    /// With no visible artefact the composite is the photo itself and no GPU work is done.
    ///
    /// # Errors
    /// `SizeMismatch` when the photo (or the shadow mask) is not the camera's size;
    /// `InvalidArgument` for invalid options, camera, lights, SH9 or environment;
    /// `TooLarge` when the photo exceeds the device's texture size; `Gpu` when the device fails.
    pub fn render(&self, inputs: &RenderInputs<'_>, options: &RenderOptions) -> Result<Composite> {
        let start = Instant::now();
        let mut timer = Timer {
            records: Vec::new(),
        };
        options.validate()?;
        let (w, h) = validate_inputs(inputs)?;
        let limits = self.device.limits();
        if w > limits.max_texture_dimension_2d || h > limits.max_texture_dimension_2d {
            return Err(Error::TooLarge(format!(
                "render: photo {w}x{h} exceeds the device's texture size {}",
                limits.max_texture_dimension_2d
            )));
        }
        let t = Instant::now();
        let geometry = SceneGeometry::build(inputs.artefacts, inputs.scene_mesh);
        if geometry.draws.is_empty() {
            timer.skipped(
                "render",
                "no visible artefact: the composite is the photo itself, no GPU work",
            );
            return Ok(photo_only(inputs, timer.records));
        }
        timer.ran(
            "render.geometry",
            t,
            format!(
                "{} artefact draws, {} vertices, scene mesh {}",
                geometry.draws.len(),
                geometry.vertices.len(),
                if geometry.scene_range.is_some() {
                    "present"
                } else {
                    "absent: no occlusion by the photo, no shadows onto it"
                }
            ),
        );

        // ---- shadow plan -------------------------------------------------------------------
        let mut shadow_size = options.shadow_map_size.min(limits.max_texture_dimension_2d);
        let mut plans = Vec::with_capacity(inputs.lights.len());
        for (i, light) in inputs.lights.iter().enumerate() {
            if options.shadows == ShadowMode::Off {
                plans.push(LightShadowPlan::Skip("shadow mode off".into()));
            } else {
                plans.push(plan(light, &geometry, shadow_size, options.filter_radius));
            }
            match &plans[i] {
                LightShadowPlan::Skip(why) => {
                    timer.skipped(&format!("render.light[{i}].shadow_map"), why.clone())
                }
                LightShadowPlan::Views(_, why) => timer.records.push(RenderRecord {
                    stage: format!("render.light[{i}].shadow_map"),
                    computed: true,
                    ms: 0.0,
                    why: why.clone(),
                }),
            }
        }
        let has_artefact_casters = geometry.caster_bounds.is_some();
        let has_scene = geometry.scene_range.is_some();
        let layers_per_view = has_artefact_casters as u32 + has_scene as u32;
        let view_count: u32 = plans
            .iter()
            .map(|p| match p {
                LightShadowPlan::Views(v, _) => v.len() as u32,
                LightShadowPlan::Skip(_) => 0,
            })
            .sum();
        // The most layers whose texture, with the layer `shadow_texture_layers` may add, stays
        // within the device's limit (the limit itself, or one or two less on OpenGL).
        let limit = limits.max_texture_array_layers;
        let max_layers = (0..=limit)
            .rev()
            .find(|&n| shadow_texture_layers(n, self.backend) <= limit)
            .unwrap_or(0);
        let mut layer_count = view_count * layers_per_view;
        if layer_count > max_layers {
            // Keep the lights that fit; the rest are unshadowed.
            let mut used = 0;
            for (i, p) in plans.iter_mut().enumerate() {
                if let LightShadowPlan::Views(v, _) = p {
                    let need = v.len() as u32 * layers_per_view;
                    if used + need > max_layers {
                        *p = LightShadowPlan::Skip("device's texture-array layer limit".into());
                        timer.skipped(
                            &format!("render.light[{i}].shadow_map"),
                            "more shadow layers than the device allows",
                        );
                    } else {
                        used += need;
                    }
                }
            }
            layer_count = used;
        }
        while shadow_size > 128
            && shadow_texture_layers(layer_count, self.backend) as u64
                * (shadow_size as u64).pow(2)
                * 8
                > SHADOW_MEMORY_BUDGET
        {
            shadow_size /= 2;
        }
        if shadow_size != options.shadow_map_size {
            timer.skipped(
                "render.shadow_map_size",
                format!(
                    "{} texels instead of {}: {} layers within the {} MiB budget and the device's limit",
                    shadow_size,
                    options.shadow_map_size,
                    layer_count,
                    SHADOW_MEMORY_BUDGET >> 20
                ),
            );
        }

        // ---- uniforms ----------------------------------------------------------------------
        let mut light_data = Vec::new();
        let mut view_data: Vec<ViewU> = Vec::new();
        let mut shadow_views: Vec<(ShadowView, i32, i32)> = Vec::new();
        let mut next_layer = 0i32;
        for (light, p) in inputs.lights.iter().zip(&plans) {
            let (first, count) = match p {
                LightShadowPlan::Views(views, _) => {
                    let first = view_data.len() as i32;
                    for v in views {
                        let art = if has_artefact_casters {
                            next_layer += 1;
                            next_layer - 1
                        } else {
                            -1
                        };
                        let scene = if has_scene {
                            next_layer += 1;
                            next_layer - 1
                        } else {
                            -1
                        };
                        view_data.push(ViewU {
                            view_proj: mat(v.view_proj),
                            origin_ortho: [
                                v.origin.x,
                                v.origin.y,
                                v.origin.z,
                                if v.orthographic { 1.0 } else { 0.0 },
                            ],
                            axis_near: [v.axis.x, v.axis.y, v.axis.z, v.near],
                            params: [v.far, v.uv_per_metre, v.light_extent, 0.0],
                            layers: [art, scene, 0, 0],
                        });
                        shadow_views.push((*v, art, scene));
                    }
                    (first, views.len() as i32)
                }
                LightShadowPlan::Skip(_) => (0, 0),
            };
            let kind = match light.kind {
                LightKind::Directional => 0.0,
                LightKind::Point => 1.0,
                LightKind::Area => 2.0,
            };
            let radius = if light.kind == LightKind::Directional {
                0.0
            } else {
                0.5 * light.size
            };
            light_data.push(LightU {
                pos_kind: [
                    light.position[0],
                    light.position[1],
                    light.position[2],
                    kind,
                ],
                dir_radius: [
                    light.direction[0],
                    light.direction[1],
                    light.direction[2],
                    radius,
                ],
                intensity: [
                    light.intensity[0],
                    light.intensity[1],
                    light.intensity[2],
                    0.0,
                ],
                shadow: [first, count, 0, 0],
            });
        }

        // Depth range of the camera: the host's near plane (artefacts crossing it are cut there),
        // and a far plane beyond everything drawn.
        let content_far = geometry
            .all_bounds()
            .map(|b| corners(&b).iter().map(|c| -c.z).fold(0.0f32, f32::max))
            .unwrap_or(0.0);
        let far = (content_far * 1.01)
            .max(inputs.camera.far)
            .max(inputs.camera.near * 2.0);
        let camera = inputs.camera.with_clip(inputs.camera.near, far)?;
        let view_proj = camera.projection_matrix(DepthEncoding::ReversedZ) * camera.view_matrix();

        let want_glossy = geometry.assets.values().any(|a| {
            a.materials
                .iter()
                .any(|m| m.roughness_factor < 0.95 || m.metallic_factor > 0.0)
        });
        let t = Instant::now();
        let (env_view, dfg_view, env_mips, has_dfg) = match (&inputs.specular, want_glossy) {
            (Some(env), true) => {
                let (c, d, mips) = upload_environment(&self.device, &self.queue, env)?;
                timer.ran(
                    "render.specular_environment",
                    t,
                    format!("{mips} prefiltered mips for glossy materials"),
                );
                (c, d, mips, true)
            }
            (Some(_), false) => {
                timer.skipped(
                    "render.specular_environment",
                    "no glossy material: prefiltered mips not needed",
                );
                let (c, d) = empty_environment(&self.device, &self.queue);
                (c, d, 0, false)
            }
            (None, _) => {
                timer.skipped(
                    "render.specular_environment",
                    "none given: specular ambient from the SH9 and an analytic DFG fit",
                );
                let (c, d) = empty_environment(&self.device, &self.queue);
                (c, d, 0, false)
            }
        };
        let spheres: Vec<[f32; 4]> = if options.ambient_occlusion {
            geometry.occluder_spheres.clone()
        } else {
            Vec::new()
        };
        let mut sh = [[0.0f32; 4]; 9];
        for (i, c) in inputs.sh9.coefficients.iter().enumerate() {
            sh[i] = [c[0], c[1], c[2], 0.0];
        }
        let frame = FrameU {
            view_proj: mat(view_proj),
            sh,
            size: [w as f32, h as f32, 0.0, 0.0],
            counts: [
                light_data.len() as u32,
                spheres.len() as u32,
                match options.shading {
                    ShadingMode::Pbr => 0,
                    ShadingMode::Thesis => 1,
                },
                match options.shadows {
                    ShadowMode::ThesisEsm => 0,
                    ShadowMode::Evsm => 1,
                    ShadowMode::Pcss => 2,
                    ShadowMode::Off => 3,
                },
            ],
            shadow: [
                options.filter_radius as f32,
                options.esm_exponent,
                options.evsm_exponents[0].min(EVSM_EXPONENT_LIMIT),
                options.evsm_exponents[1].min(EVSM_EXPONENT_LIMIT),
            ],
            flags: [
                shadow_size as f32,
                if inputs.photo_shadow.is_some() {
                    1.0
                } else {
                    0.0
                },
                env_mips as f32,
                if has_dfg { 1.0 } else { 0.0 },
            ],
        };
        let device = &self.device;
        let formats = self.pipelines.formats;
        // Device errors (out of memory for large shadow maps, validation) become `Error::Gpu`
        // instead of wgpu's default panic; scopes pop in reverse order.
        let oom_scope = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation_scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let storage = |label: &str, bytes: &[u8]| {
            // Storage bindings may not be empty.
            let padded: Vec<u8> = if bytes.is_empty() {
                vec![0u8; 256]
            } else {
                bytes.to_vec()
            };
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &padded,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let frame_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("parallax frame"),
            contents: bytemuck::bytes_of(&frame),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let light_buffer = storage("parallax lights", bytemuck::cast_slice(&light_data));
        let view_buffer = storage("parallax shadow views", bytemuck::cast_slice(&view_data));
        let sphere_buffer = storage("parallax occluder spheres", bytemuck::cast_slice(&spheres));
        let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("parallax vertices"),
            contents: bytemuck::cast_slice(&geometry.vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let index_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("parallax indices"),
            contents: bytemuck::cast_slice(&geometry.indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        let t = Instant::now();
        let materials = Materials::build(
            device,
            &self.queue,
            &self.pipelines,
            &geometry.assets,
            geometry.draws.iter().filter_map(|d| d.material),
        )?;
        timer.ran(
            "render.materials",
            t,
            format!(
                "{} materials, {} textures uploaded",
                materials.groups.len(),
                materials.texture_count
            ),
        );
        let material_of = |d: &super::geometry::Draw| {
            d.material
                .and_then(|k| materials.groups.get(&k))
                .unwrap_or(&materials.default)
        };

        // ---- shadow maps -------------------------------------------------------------------
        let t = Instant::now();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("parallax render"),
        });
        let shadow_texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("parallax shadow maps"),
            size: wgpu::Extent3d {
                width: if layer_count > 0 { shadow_size } else { 1 },
                height: if layer_count > 0 { shadow_size } else { 1 },
                depth_or_array_layers: shadow_texture_layers(layer_count, self.backend),
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: formats.shadow,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        if layer_count > 0 {
            let align = limits.min_uniform_buffer_offset_alignment.max(256) as usize;
            let mut pass_data = vec![0u8; align * shadow_views.len().max(1)];
            for (i, (v, _, _)) in shadow_views.iter().enumerate() {
                let u = ShadowPassU {
                    view_proj: mat(v.view_proj),
                    origin_ortho: [
                        v.origin.x,
                        v.origin.y,
                        v.origin.z,
                        if v.orthographic { 1.0 } else { 0.0 },
                    ],
                    axis: [v.axis.x, v.axis.y, v.axis.z, 0.0],
                };
                pass_data[i * align..i * align + std::mem::size_of::<ShadowPassU>()]
                    .copy_from_slice(bytemuck::bytes_of(&u));
            }
            let pass_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("parallax shadow passes"),
                contents: &pass_data,
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let pass_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("parallax shadow pass"),
                layout: &self.pipelines.shadow_pass_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &pass_buffer,
                        offset: 0,
                        size: wgpu::BufferSize::new(std::mem::size_of::<ShadowPassU>() as u64),
                    }),
                }],
            });
            let depth = target(
                device,
                "parallax shadow depth",
                (shadow_size, shadow_size),
                DEPTH_FORMAT,
                1,
                false,
            );
            let depth_view = depth.create_view(&Default::default());
            for (i, (_, art, scene)) in shadow_views.iter().enumerate() {
                for (layer, artefacts) in [(*art, true), (*scene, false)] {
                    if layer < 0 {
                        continue;
                    }
                    let layer_view = shadow_texture.create_view(&wgpu::TextureViewDescriptor {
                        dimension: Some(wgpu::TextureViewDimension::D2),
                        base_array_layer: layer as u32,
                        array_layer_count: Some(1),
                        ..Default::default()
                    });
                    let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("parallax shadow map"),
                        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                            view: &layer_view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                // "No occluder": farther than anything.
                                load: wgpu::LoadOp::Clear(wgpu::Color {
                                    r: f32::MAX as f64,
                                    g: 0.0,
                                    b: 0.0,
                                    a: 1.0,
                                }),
                                store: wgpu::StoreOp::Store,
                            },
                        })],
                        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                            view: &depth_view,
                            depth_ops: Some(wgpu::Operations {
                                load: wgpu::LoadOp::Clear(0.0),
                                store: wgpu::StoreOp::Discard,
                            }),
                            stencil_ops: None,
                        }),
                        timestamp_writes: None,
                        occlusion_query_set: None,
                        multiview_mask: None,
                    });
                    pass.set_pipeline(&self.pipelines.shadow);
                    pass.set_vertex_buffer(0, vertex_buffer.slice(..));
                    pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
                    pass.set_bind_group(0, &pass_group, &[(i * align) as u32]);
                    if artefacts {
                        for d in geometry.draws.iter().filter(|d| d.casts_shadow) {
                            pass.set_bind_group(1, material_of(d), &[]);
                            pass.draw_indexed(
                                d.first_index..d.first_index + d.index_count,
                                0,
                                0..1,
                            );
                        }
                    } else if let Some((first, count)) = geometry.scene_range {
                        pass.set_bind_group(1, &materials.default, &[]);
                        pass.draw_indexed(first..first + count, 0, 0..1);
                    }
                }
            }
        }
        timer.ran(
            "render.shadow_maps.encode",
            t,
            format!(
                "{} views × {} layers of {}² texels",
                shadow_views.len(),
                layers_per_view,
                shadow_size
            ),
        );

        // ---- frame bind group --------------------------------------------------------------
        let shadow_array = shadow_texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let mask_view = mask_texture(device, &self.queue, inputs.photo_shadow);
        let env_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("parallax environment sampler"),
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            address_mode_w: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });
        let frame_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("parallax frame"),
            layout: &self.pipelines.frame_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: frame_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: light_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: view_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&shadow_array),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: sphere_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::TextureView(&env_view),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: wgpu::BindingResource::TextureView(&dfg_view),
                },
                wgpu::BindGroupEntry {
                    binding: 7,
                    resource: wgpu::BindingResource::Sampler(&env_sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 8,
                    resource: wgpu::BindingResource::TextureView(&mask_view),
                },
            ],
        });

        // ---- artefacts (MSAA), hidden by the scene mesh's depth ------------------------------
        let samples = if options.msaa { 4 } else { 1 };
        let forward = &self.pipelines.forward[options.msaa as usize];
        let layer = target(
            device,
            "parallax artefact layer",
            (w, h),
            LAYER_FORMAT,
            1,
            true,
        );
        let layer_view = layer.create_view(&Default::default());
        let msaa_color = (samples > 1).then(|| {
            target(
                device,
                "parallax artefact layer (MSAA)",
                (w, h),
                LAYER_FORMAT,
                samples,
                false,
            )
        });
        let msaa_view = msaa_color
            .as_ref()
            .map(|t| t.create_view(&Default::default()));
        let forward_depth = target(
            device,
            "parallax camera depth",
            (w, h),
            DEPTH_FORMAT,
            samples,
            false,
        );
        let forward_depth_view = forward_depth.create_view(&Default::default());
        {
            let (view, resolve) = match &msaa_view {
                Some(m) => (m, Some(&layer_view)),
                None => (&layer_view, None),
            };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("parallax artefacts"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: resolve,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &forward_depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_vertex_buffer(0, vertex_buffer.slice(..));
            pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
            pass.set_bind_group(0, &frame_group, &[]);
            if let Some((first, count)) = geometry.scene_range {
                pass.set_pipeline(&forward.depth_only);
                pass.set_bind_group(1, &materials.default, &[]);
                pass.draw_indexed(first..first + count, 0, 0..1);
            }
            for d in &geometry.draws {
                pass.set_pipeline(forward.artefact(DrawKind {
                    blend: d.blend,
                    double_sided: d.double_sided,
                }));
                pass.set_bind_group(1, material_of(d), &[]);
                pass.draw_indexed(d.first_index..d.first_index + d.index_count, 0, 0..1);
            }
        }

        // ---- shadow ratio on the scene mesh, and the artefacts' depth -----------------------
        let ratio = target(
            device,
            "parallax shadow ratio",
            (w, h),
            formats.ratio,
            1,
            true,
        );
        let ratio_view = ratio.create_view(&Default::default());
        let art_depth = target(
            device,
            "parallax artefact depth",
            (w, h),
            formats.artefact_depth,
            1,
            true,
        );
        let art_depth_view = art_depth.create_view(&Default::default());
        let receiver_depth = target(
            device,
            "parallax receiver depth",
            (w, h),
            DEPTH_FORMAT,
            1,
            false,
        );
        let receiver_depth_view = receiver_depth.create_view(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("parallax shadow ratio"),
                color_attachments: &[
                    Some(wgpu::RenderPassColorAttachment {
                        view: &ratio_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::WHITE),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                    Some(wgpu::RenderPassColorAttachment {
                        view: &art_depth_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                ],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &receiver_depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_vertex_buffer(0, vertex_buffer.slice(..));
            pass.set_index_buffer(index_buffer.slice(..), wgpu::IndexFormat::Uint32);
            pass.set_bind_group(0, &frame_group, &[]);
            if let Some((first, count)) = geometry.scene_range {
                pass.set_pipeline(&self.pipelines.receiver_scene);
                pass.set_bind_group(1, &materials.default, &[]);
                pass.draw_indexed(first..first + count, 0, 0..1);
            }
            for d in geometry.draws.iter().filter(|d| !d.blend) {
                pass.set_pipeline(&self.pipelines.receiver_artefact[d.double_sided as usize]);
                pass.set_bind_group(1, material_of(d), &[]);
                pass.draw_indexed(d.first_index..d.first_index + d.index_count, 0, 0..1);
            }
        }
        let t = Instant::now();
        self.queue.submit([encoder.finish()]);
        for scope in [validation_scope, oom_scope] {
            if let Some(e) = pollster::block_on(scope.pop()) {
                return Err(Error::Gpu(format!(
                    "render: the device failed: {}",
                    wgpu_error_text(&e)
                )));
            }
        }
        let layer_bytes = read_texture(device, &self.queue, &layer)?;
        let ratio_bytes = read_texture(device, &self.queue, &ratio)?;
        let depth_bytes = read_texture(device, &self.queue, &art_depth)?;
        timer.ran(
            "render.gpu",
            t,
            format!(
                "shadow maps, artefacts ({samples}× MSAA, {} shading), shadow ratio{}; read back{}",
                match options.shading {
                    ShadingMode::Pbr => "PBR",
                    ShadingMode::Thesis => "thesis",
                },
                if has_scene {
                    ""
                } else {
                    " (no scene mesh: ratio 1)"
                },
                if formats == TargetFormats::FLOAT32 {
                    ""
                } else {
                    "; 16-bit float targets (the device cannot render into 32-bit floats)"
                }
            ),
        );

        // ---- composite ---------------------------------------------------------------------
        let t = Instant::now();
        let layer_texels = float_texels(&layer_bytes, LAYER_FORMAT);
        let ratios = float_texels(&ratio_bytes, formats.ratio);
        let depths = float_texels(&depth_bytes, formats.artefact_depth);
        let (wu, hu) = (w as usize, h as usize);
        let finite = |v: f32, lo: f32, hi: f32| if v.is_finite() { v.clamp(lo, hi) } else { lo };
        let artefact_layer = Raster::from_fn(wu, hu, |x, y| {
            let i = (y * wu + x) * 4;
            let a = finite(layer_texels[i + 3], 0.0, 1.0);
            [
                finite(layer_texels[i], 0.0, 65504.0),
                finite(layer_texels[i + 1], 0.0, 65504.0),
                finite(layer_texels[i + 2], 0.0, 65504.0),
                a,
            ]
        });
        let shadow_ratio = Raster::from_fn(wu, hu, |x, y| {
            let i = (y * wu + x) * 4;
            [0, 1, 2].map(|k| {
                let r = ratios[i + k];
                if r.is_finite() {
                    r.clamp(0.0, 1.0)
                } else {
                    1.0
                }
            })
        });
        // An artefact beyond a 16-bit target's range (65504 m) reads back as +∞: far, not absent.
        let artefact_depth = Raster::from_fn(wu, hu, |x, y| match depths[y * wu + x] {
            f32::INFINITY => f32::MAX,
            d => finite(d, 0.0, f32::MAX),
        });
        let mask = artefact_layer.map(|p| p[3]);
        let composite = Raster::from_fn(wu, hu, |x, y| {
            let p = inputs.photo.get(x, y);
            let r = shadow_ratio.get(x, y);
            let a = artefact_layer.get(x, y);
            [0, 1, 2].map(|k| finite(p[k], 0.0, f32::MAX) * r[k] * (1.0 - a[3]) + a[k])
        });
        timer.ran(
            "render.composite",
            t,
            "photo × ratio + artefacts (premultiplied)",
        );
        timer.records.push(RenderRecord {
            stage: "render".into(),
            computed: true,
            ms: start.elapsed().as_secs_f64() * 1e3,
            why: format!(
                "{} lights, {} artefact draws",
                inputs.lights.len(),
                geometry.draws.len()
            ),
        });
        Ok(Composite {
            composite,
            mask,
            shadow_ratio,
            artefact_depth,
            artefact_layer,
            records: timer.records,
        })
    }
}

fn validate_inputs(inputs: &RenderInputs<'_>) -> Result<(u32, u32)> {
    inputs.camera.validate()?;
    let (w, h) = (inputs.camera.width, inputs.camera.height);
    if inputs.photo.width() != w as usize || inputs.photo.height() != h as usize {
        return Err(Error::SizeMismatch(format!(
            "render: the photo is {}x{} but the camera is {w}x{h}",
            inputs.photo.width(),
            inputs.photo.height()
        )));
    }
    if let Some(mask) = inputs.photo_shadow {
        if mask.width() != w as usize || mask.height() != h as usize {
            return Err(Error::SizeMismatch(format!(
                "render: the photo shadow mask is {}x{} but the photo is {w}x{h}",
                mask.width(),
                mask.height()
            )));
        }
        if let Some(v) = mask.pixels().iter().find(|v| !v.is_finite()) {
            return Err(Error::invalid(format!(
                "render: the photo shadow mask holds a non-finite value {v}"
            )));
        }
    }
    for (i, l) in inputs.lights.iter().enumerate() {
        l.validate()
            .map_err(|e| Error::invalid(format!("render: light {i}: {e}")))?;
    }
    if let Some(c) = inputs
        .sh9
        .coefficients
        .iter()
        .flatten()
        .find(|c| !c.is_finite())
    {
        return Err(Error::invalid(format!(
            "render: SH9 coefficient {c} is not finite"
        )));
    }
    Ok((w, h))
}

/// The photo itself (non-finite values made 0), ratio 1, no artefact.
fn photo_only(inputs: &RenderInputs<'_>, records: Vec<RenderRecord>) -> Composite {
    let (w, h) = (inputs.photo.width(), inputs.photo.height());
    Composite {
        composite: inputs
            .photo
            .map(|p| p.map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 })),
        mask: Raster::filled(w, h, 0.0),
        shadow_ratio: Raster::filled(w, h, [1.0; 3]),
        artefact_depth: Raster::filled(w, h, 0.0),
        artefact_layer: Raster::filled(w, h, [0.0; 4]),
        records,
    }
}

#[cfg(test)]
mod tests {
    use super::shadow_texture_layers;

    /// wgpu's OpenGL backend takes a 2D texture of one layer for a plain 2D texture and a square
    /// one with 6·k layers for a cube (array); the shadow maps must never have such a count
    /// there, and need at least one layer anywhere.
    #[test]
    fn shadow_maps_are_always_a_2d_array_on_opengl() {
        for used in 0..=200u32 {
            let gl = shadow_texture_layers(used, wgpu::Backend::Gl);
            assert!(gl >= used.max(2) && gl <= used.max(1) + 1, "{used} → {gl}");
            assert_ne!(gl % 6, 0, "{used} layers on OpenGL");
            let vulkan = shadow_texture_layers(used, wgpu::Backend::Vulkan);
            assert_eq!(vulkan, used.max(1));
        }
    }
}
