//! Bind-group layouts and render pipelines, created once per [`super::Renderer`].

use super::geometry::Vertex;

/// Colour format of the artefact layer (premultiplied linear RGBA).
pub(crate) const LAYER_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// Formats of the float render targets that are read back or sampled as data.
///
/// WebGPU can render into 32-bit floats everywhere, but wgpu's OpenGL backend cannot on every
/// driver: on Mesa's llvmpipe it reports only 16-bit floats as renderable. The renderer then
/// falls back to [`TargetFormats::FLOAT16`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct TargetFormats {
    /// Shadow maps: linear distance from the light, metres.
    pub shadow: wgpu::TextureFormat,
    /// Shadow ratio (RGB, alpha unused).
    pub ratio: wgpu::TextureFormat,
    /// Artefact depth along the view axis, metres.
    pub artefact_depth: wgpu::TextureFormat,
}

impl TargetFormats {
    /// 32-bit floats: the default.
    pub const FLOAT32: TargetFormats = TargetFormats {
        shadow: wgpu::TextureFormat::R32Float,
        ratio: wgpu::TextureFormat::Rgba32Float,
        artefact_depth: wgpu::TextureFormat::R32Float,
    };
    /// 16-bit floats, for devices that cannot render into 32-bit ones: shadow distances split
    /// over two channels, the artefact depth to 11 significant bits (0.05 %), at most 65504 m.
    pub const FLOAT16: TargetFormats = TargetFormats {
        shadow: wgpu::TextureFormat::Rgba16Float,
        ratio: wgpu::TextureFormat::Rgba16Float,
        artefact_depth: wgpu::TextureFormat::R16Float,
    };

    /// Whether a shadow-map texel holds its distance as two halves, the distance rounded to f16
    /// in red and the remainder in green: 16-bit floats alone keep 11 bits, under the shadow
    /// test's bias a few metres away; the pair keeps about 22.
    pub fn split_shadow_distance(&self) -> bool {
        self.shadow == wgpu::TextureFormat::Rgba16Float
    }
}
/// Every depth buffer (reversed Z: 1 near, 0 far; compare `GreaterEqual`).
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 7] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32, 2 => Float32x3, 3 => Float32x4, 4 => Float32x2,
    5 => Float32x2, 6 => Float32x4
];

fn vertex_layout() -> wgpu::VertexBufferLayout<'static> {
    wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &VERTEX_ATTRIBUTES,
    }
}

fn uniform_entry(binding: u32, dynamic: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

fn storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn texture_entry(
    binding: u32,
    dimension: wgpu::TextureViewDimension,
    filterable: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable },
            view_dimension: dimension,
            multisampled: false,
        },
        count: None,
    }
}

fn sampler_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

/// Which artefact draw a pipeline is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct DrawKind {
    pub blend: bool,
    pub double_sided: bool,
}

pub(crate) struct Pipelines {
    pub frame_layout: wgpu::BindGroupLayout,
    pub material_layout: wgpu::BindGroupLayout,
    pub shadow_pass_layout: wgpu::BindGroupLayout,
    pub shadow: wgpu::RenderPipeline,
    /// Forward pass pipelines per sample count (index 0: 1×, 1: 4×).
    pub forward: [ForwardPipelines; 2],
    pub receiver_scene: wgpu::RenderPipeline,
    pub receiver_artefact: [wgpu::RenderPipeline; 2],
    /// The formats the shadow and receiver pipelines write.
    pub formats: TargetFormats,
}

pub(crate) struct ForwardPipelines {
    pub depth_only: wgpu::RenderPipeline,
    /// Indexed by `blend as usize * 2 + double_sided as usize`.
    pub artefact: [wgpu::RenderPipeline; 4],
}

impl ForwardPipelines {
    pub fn artefact(&self, kind: DrawKind) -> &wgpu::RenderPipeline {
        &self.artefact[kind.blend as usize * 2 + kind.double_sided as usize]
    }
}

fn depth_state(write: bool) -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(write),
        // Not `Greater`: wgpu's OpenGL backend maps clip z from [0, 1] to [−1, 1] as `2z − w`,
        // which rounds reversed depths under about 3·10⁻⁸ (beyond about 3·10⁷ near-plane
        // distances, or the last few percent of a shadow frustum whose near plane is 10⁻⁶ of
        // its far) to exactly the cleared 0; they must still pass.
        depth_compare: Some(wgpu::CompareFunction::GreaterEqual),
        stencil: wgpu::StencilState::default(),
        bias: wgpu::DepthBiasState::default(),
    }
}

struct PipelineSpec<'a> {
    label: &'a str,
    layout: &'a wgpu::PipelineLayout,
    module: &'a wgpu::ShaderModule,
    vs: &'a str,
    fs: &'a str,
    targets: &'a [Option<wgpu::ColorTargetState>],
    cull: Option<wgpu::Face>,
    depth_write: bool,
    samples: u32,
    /// Values of the fragment shader's pipeline-overridable constants.
    constants: &'a [(&'a str, f64)],
}

fn pipeline(device: &wgpu::Device, spec: PipelineSpec<'_>) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(spec.label),
        layout: Some(spec.layout),
        vertex: wgpu::VertexState {
            module: spec.module,
            entry_point: Some(spec.vs),
            compilation_options: Default::default(),
            buffers: &[Some(vertex_layout())],
        },
        fragment: Some(wgpu::FragmentState {
            module: spec.module,
            entry_point: Some(spec.fs),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: spec.constants,
                ..Default::default()
            },
            targets: spec.targets,
        }),
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: spec.cull,
            ..Default::default()
        },
        depth_stencil: Some(depth_state(spec.depth_write)),
        multisample: wgpu::MultisampleState {
            count: spec.samples,
            mask: !0,
            alpha_to_coverage_enabled: false,
        },
        multiview_mask: None,
        cache: None,
    })
}

impl Pipelines {
    pub fn new(device: &wgpu::Device, formats: TargetFormats) -> Pipelines {
        use wgpu::TextureViewDimension as D;
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("parallax frame"),
            entries: &[
                uniform_entry(0, false),
                storage_entry(1),
                storage_entry(2),
                texture_entry(3, D::D2Array, false),
                storage_entry(4),
                texture_entry(5, D::Cube, true),
                texture_entry(6, D::D2, true),
                sampler_entry(7),
                texture_entry(8, D::D2, false),
            ],
        });
        let mut material_entries = vec![uniform_entry(0, false)];
        material_entries.extend((1..=5).map(|b| texture_entry(b, D::D2, true)));
        material_entries.extend((6..=10).map(sampler_entry));
        let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("parallax material"),
            entries: &material_entries,
        });
        let shadow_pass_layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("parallax shadow pass"),
                entries: &[uniform_entry(0, true)],
            });

        let material_wgsl = include_str!("material.wgsl");
        let common_wgsl = include_str!("common.wgsl");
        let shadow_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("parallax shadow.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                format!("{material_wgsl}\n{}", include_str!("shadow.wgsl")).into(),
            ),
        });
        let forward_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("parallax forward.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                format!(
                    "{common_wgsl}\n{material_wgsl}\n{}",
                    include_str!("forward.wgsl")
                )
                .into(),
            ),
        });
        let receiver_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("parallax receiver.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                format!(
                    "{common_wgsl}\n{material_wgsl}\n{}",
                    include_str!("receiver.wgsl")
                )
                .into(),
            ),
        });

        let shadow_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("parallax shadow"),
            bind_group_layouts: &[Some(&shadow_pass_layout), Some(&material_layout)],
            immediate_size: 0,
        });
        let main_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("parallax main"),
            bind_group_layouts: &[Some(&frame_layout), Some(&material_layout)],
            immediate_size: 0,
        });

        // Shadow casters are drawn from both sides: the nearest surface is what blocks light.
        let shadow = pipeline(
            device,
            PipelineSpec {
                label: "parallax shadow map",
                layout: &shadow_layout,
                module: &shadow_module,
                vs: "vs_shadow",
                fs: "fs_shadow",
                targets: &[Some(formats.shadow.into())],
                cull: None,
                depth_write: true,
                samples: 1,
                constants: &[(
                    "SPLIT_DISTANCE",
                    formats.split_shadow_distance() as u8 as f64,
                )],
            },
        );

        let forward_for = |samples: u32| {
            let hidden = [Some(wgpu::ColorTargetState {
                format: LAYER_FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::empty(),
            })];
            let depth_only = pipeline(
                device,
                PipelineSpec {
                    label: "parallax scene depth",
                    layout: &main_layout,
                    module: &forward_module,
                    vs: "vs_camera",
                    fs: "fs_depth_only",
                    targets: &hidden,
                    cull: None,
                    depth_write: true,
                    samples,
                    constants: &[],
                },
            );
            let artefact = std::array::from_fn(|i| {
                let blend = i >= 2;
                let double_sided = i % 2 == 1;
                let targets = [Some(wgpu::ColorTargetState {
                    format: LAYER_FORMAT,
                    blend: Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
                    write_mask: wgpu::ColorWrites::ALL,
                })];
                pipeline(
                    device,
                    PipelineSpec {
                        label: "parallax artefact",
                        layout: &main_layout,
                        module: &forward_module,
                        vs: "vs_camera",
                        fs: "fs_artefact",
                        targets: &targets,
                        cull: if double_sided {
                            None
                        } else {
                            Some(wgpu::Face::Back)
                        },
                        depth_write: !blend,
                        samples,
                        constants: &[],
                    },
                )
            });
            ForwardPipelines {
                depth_only,
                artefact,
            }
        };
        let forward = [forward_for(1), forward_for(4)];

        let receiver_targets = |ratio: bool| {
            [
                Some(wgpu::ColorTargetState {
                    format: formats.ratio,
                    blend: None,
                    write_mask: if ratio {
                        wgpu::ColorWrites::ALL
                    } else {
                        wgpu::ColorWrites::empty()
                    },
                }),
                Some(wgpu::ColorTargetState {
                    format: formats.artefact_depth,
                    blend: None,
                    write_mask: if ratio {
                        wgpu::ColorWrites::empty()
                    } else {
                        wgpu::ColorWrites::ALL
                    },
                }),
            ]
        };
        let receiver_scene = pipeline(
            device,
            PipelineSpec {
                label: "parallax receiver",
                layout: &main_layout,
                module: &receiver_module,
                vs: "vs_camera",
                fs: "fs_receiver",
                targets: &receiver_targets(true),
                cull: None,
                depth_write: true,
                samples: 1,
                constants: &[],
            },
        );
        let receiver_artefact = std::array::from_fn(|i| {
            pipeline(
                device,
                PipelineSpec {
                    label: "parallax artefact depth",
                    layout: &main_layout,
                    module: &receiver_module,
                    vs: "vs_camera",
                    fs: "fs_artefact_depth",
                    targets: &receiver_targets(false),
                    cull: if i == 1 { None } else { Some(wgpu::Face::Back) },
                    depth_write: true,
                    samples: 1,
                    constants: &[],
                },
            )
        });
        Pipelines {
            frame_layout,
            material_layout,
            shadow_pass_layout,
            shadow,
            forward,
            receiver_scene,
            receiver_artefact,
            formats,
        }
    }
}
