//! The headless wgpu context: adapter choice, device creation, and texture readback.
//!
//! Follows wgpu's headless examples: no surface, render into a texture, copy it into a buffer
//! whose rows are padded to [`wgpu::COPY_BYTES_PER_ROW_ALIGNMENT`] (256 bytes), map, unpad.

use std::fmt;

use crate::error::{Error, Result};

/// Which GPU adapter to use.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GpuOptions {
    /// Use the first adapter whose name contains this text (case-insensitive). When `None`, the
    /// `WGPU_ADAPTER_NAME` environment variable is used, and failing that the first discrete GPU,
    /// then integrated, virtual, other, and last a CPU (software) adapter.
    pub adapter_name: Option<String>,
}

/// A description of an adapter, as `parallax info` prints it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AdapterDescription {
    /// Adapter name, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
    pub name: String,
    /// Backend, e.g. "Vulkan".
    pub backend: String,
    /// Device type: "DiscreteGpu", "Cpu", …
    pub device_type: String,
    /// Driver name and version information.
    pub driver: String,
}

impl fmt::Display for AdapterDescription {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} ({}, {}, driver {})",
            self.name, self.backend, self.device_type, self.driver
        )
    }
}

impl From<wgpu::AdapterInfo> for AdapterDescription {
    fn from(info: wgpu::AdapterInfo) -> Self {
        AdapterDescription {
            name: info.name,
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
        }
    }
}

const NO_ADAPTER: &str = "no GPU adapter: install a Vulkan driver, e.g. mesa-vulkan-drivers";

/// The backends to try: `WGPU_BACKEND` when set (e.g. "vulkan", "gl"), else Vulkan/Metal/DX12,
/// else OpenGL. OpenGL comes last because its EGL start-up is slow and noisy where a Vulkan
/// driver exists.
fn backend_choices() -> Vec<wgpu::Backends> {
    match wgpu::Backends::from_env() {
        Some(b) => vec![b],
        None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::GL],
    }
}

fn instance(backends: wgpu::Backends) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    desc.backends = backends;
    wgpu::Instance::new(desc)
}

/// Adapters of the first backend group that has any (see `WGPU_BACKEND`), with the instance that
/// found them.
pub(super) fn find_adapters() -> Option<(wgpu::Instance, Vec<wgpu::Adapter>)> {
    backend_choices().into_iter().find_map(|backends| {
        let instance = instance(backends);
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        (!adapters.is_empty()).then_some((instance, adapters))
    })
}

/// Every adapter wgpu finds (see [`GpuContext::new`] for the order of backends).
pub fn list_adapters() -> Vec<AdapterDescription> {
    find_adapters()
        .map(|(_, adapters)| adapters.into_iter().map(|a| a.get_info().into()).collect())
        .unwrap_or_default()
}

/// An open GPU device and its queue.
#[derive(Debug)]
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter it was opened on.
    pub adapter: AdapterDescription,
    /// The adapter's limits (the device is opened with these, so large shadow maps can be used
    /// where the hardware allows).
    pub limits: wgpu::Limits,
    /// Whether 32-bit float textures can be filtered on this device.
    pub float32_filterable: bool,
}

impl GpuContext {
    /// Finds an adapter (see [`GpuOptions`]) and opens a device on it.
    ///
    /// # Errors
    /// `Gpu` when no adapter exists ("no GPU adapter: install a Vulkan driver, e.g.
    /// mesa-vulkan-drivers"), when no adapter matches the requested name, or when the device
    /// cannot be created.
    pub fn new(options: &GpuOptions) -> Result<Self> {
        let (_instance, adapters) = find_adapters().ok_or_else(|| Error::Gpu(NO_ADAPTER.into()))?;
        let wanted = options
            .adapter_name
            .clone()
            .or_else(|| std::env::var("WGPU_ADAPTER_NAME").ok())
            .filter(|s| !s.is_empty());
        let adapter = match &wanted {
            Some(name) => {
                let needle = name.to_lowercase();
                let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
                adapters
                    .into_iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&needle))
                    .ok_or_else(|| {
                        Error::Gpu(format!(
                            "no GPU adapter named like {name:?}; found: {}",
                            names.join(", ")
                        ))
                    })?
            }
            // wgpu's own preference order: discrete, integrated, virtual, CPU.
            None => adapters
                .into_iter()
                .min_by_key(|a| match a.get_info().device_type {
                    wgpu::DeviceType::DiscreteGpu => 0,
                    wgpu::DeviceType::IntegratedGpu => 1,
                    wgpu::DeviceType::VirtualGpu => 2,
                    wgpu::DeviceType::Other => 3,
                    wgpu::DeviceType::Cpu => 4,
                })
                .ok_or_else(|| Error::Gpu(NO_ADAPTER.into()))?,
        };
        let limits = adapter.limits();
        let float32_filterable = adapter
            .features()
            .contains(wgpu::Features::FLOAT32_FILTERABLE);
        let required_features = if float32_filterable {
            wgpu::Features::FLOAT32_FILTERABLE
        } else {
            wgpu::Features::empty()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("parallax"),
            required_features,
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| {
            Error::Gpu(format!(
                "cannot open a device on {}: {e}",
                adapter.get_info().name
            ))
        })?;
        Ok(GpuContext {
            device,
            queue,
            adapter: adapter.get_info().into(),
            limits,
            float32_filterable,
        })
    }

    /// Copies a 2D texture (mip 0, layer 0) into tightly packed rows of bytes.
    ///
    /// The texture must have `COPY_SRC` usage and an uncompressed colour format.
    ///
    /// # Errors
    /// `Gpu` when the format has no fixed texel size, or mapping the buffer fails.
    pub fn read_texture(&self, texture: &wgpu::Texture) -> Result<Vec<u8>> {
        read_texture(&self.device, &self.queue, texture)
    }
}

/// Copies a 2D texture (mip 0, layer 0) into tightly packed rows of bytes, on any device (a
/// host's own included).
///
/// The texture must have `COPY_SRC` usage and an uncompressed colour format.
///
/// # Errors
/// `Gpu` when the format has no fixed texel size, or mapping the buffer fails.
pub fn read_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
) -> Result<Vec<u8>> {
    let format = texture.format();
    let texel = format
        .block_copy_size(None)
        .ok_or_else(|| Error::Gpu(format!("cannot read back texture format {format:?}")))?
        as usize;
    let (width, height) = (texture.width() as usize, texture.height() as usize);
    let row = width * texel;
    let padded_row = padded_bytes_per_row(row);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("parallax readback"),
        size: (padded_row * height) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("parallax readback"),
    });
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded_row as u32),
                rows_per_image: Some(height as u32),
            },
        },
        texture.size(),
    );
    queue.submit([encoder.finish()]);
    let slice = buffer.slice(..);
    let (sender, receiver) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        // The receiver lives until after the poll below; a failed send only means it is gone.
        let _ = sender.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu(format!("waiting for the GPU failed: {e}")))?;
    receiver
        .recv()
        .map_err(|_| Error::Gpu("readback callback never ran".into()))?
        .map_err(|e| Error::Gpu(format!("mapping the readback buffer failed: {e}")))?;
    let mapped = slice
        .get_mapped_range()
        .map_err(|e| Error::Gpu(format!("reading the readback buffer failed: {e}")))?;
    let mut out = Vec::with_capacity(row * height);
    for y in 0..height {
        out.extend_from_slice(&mapped[y * padded_row..y * padded_row + row]);
    }
    drop(mapped);
    buffer.unmap();
    Ok(out)
}

/// `row` rounded up to wgpu's 256-byte row alignment for buffer copies.
pub fn padded_bytes_per_row(row: usize) -> usize {
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as usize;
    row.div_ceil(align) * align
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_padded_to_256_bytes() {
        assert_eq!(padded_bytes_per_row(1), 256);
        assert_eq!(padded_bytes_per_row(256), 256);
        assert_eq!(padded_bytes_per_row(257), 512);
        assert_eq!(padded_bytes_per_row(4 * 100), 512);
    }

    #[test]
    fn a_missing_adapter_name_is_a_clear_error() {
        let err = GpuContext::new(&GpuOptions {
            adapter_name: Some("no-such-adapter-xyz".into()),
        })
        .unwrap_err();
        let message = err.to_string();
        assert!(
            message.contains("no-such-adapter-xyz") || message.contains("mesa-vulkan-drivers"),
            "{message}"
        );
    }

    /// Renders one triangle that covers the left half of a 67×33 target (an odd width, so rows
    /// need padding) and checks pixels inside, outside and across the diagonal.
    #[test]
    fn renders_a_known_triangle_and_reads_it_back() {
        let gpu = GpuContext::new(&GpuOptions::default()).expect(
            "a GPU adapter is required for this test (CI installs mesa-vulkan-drivers for llvmpipe)",
        );
        let (w, h) = (67u32, 33u32);
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let target = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("triangle target"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let shader = gpu
            .device
            .create_shader_module(wgpu::include_wgsl!("test_triangle.wgsl"));
        let pipeline = gpu
            .device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("triangle"),
                layout: None,
                vertex: wgpu::VertexState {
                    module: &shader,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                fragment: Some(wgpu::FragmentState {
                    module: &shader,
                    entry_point: Some("fs_main"),
                    compilation_options: Default::default(),
                    targets: &[Some(format.into())],
                }),
                primitive: wgpu::PrimitiveState::default(),
                depth_stencil: None,
                multisample: wgpu::MultisampleState::default(),
                multiview_mask: None,
                cache: None,
            });
        let view = target.create_view(&Default::default());
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("triangle"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLUE),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&pipeline);
            pass.draw(0..3, 0..1);
        }
        gpu.queue.submit([encoder.finish()]);
        let pixels = gpu.read_texture(&target).unwrap();
        assert_eq!(pixels.len(), (w * h * 4) as usize);
        let at = |x: u32, y: u32| {
            let i = ((y * w + x) * 4) as usize;
            [pixels[i], pixels[i + 1], pixels[i + 2], pixels[i + 3]]
        };
        // The triangle has NDC corners (-1,-1), (0,-1), (-1,1): the lower-left half of the left half.
        assert_eq!(at(2, h - 2), [255, 0, 0, 255], "inside the triangle");
        assert_eq!(
            at(w - 2, 2),
            [0, 0, 255, 255],
            "right half is the clear colour"
        );
        assert_eq!(at(w / 2 - 2, 2), [0, 0, 255, 255], "above the diagonal");
        assert_eq!(at(2, 2), [255, 0, 0, 255], "top-left corner is inside");
        let red = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| at(x, y) == [255, 0, 0, 255])
            .count();
        // Area of the triangle: a quarter of the target.
        let expected = (w * h) as f64 / 4.0;
        assert!(
            (red as f64 - expected).abs() < 0.05 * expected,
            "{red} red pixels, expected ~{expected}"
        );
    }
}
