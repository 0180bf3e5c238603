//! What scenes of one host share: size caps and the GPU, opened the first time a stage needs it.

#[cfg(feature = "gpu")]
use std::sync::Arc;
use std::sync::Mutex;

#[cfg(feature = "gpu")]
use crate::error::Error;
use crate::error::Result;
use crate::image::ImageLimits;

/// Options of a [`Context`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ContextOptions {
    /// Size caps for every image a scene accepts.
    pub limits: ImageLimits,
    /// Adapter to use: the first whose name contains this text (else `WGPU_ADAPTER_NAME`, else
    /// the best available; see [`crate::render::GpuOptions`]).
    pub adapter_name: Option<String>,
}

/// Shared by the scenes of one host. Thread-safe: scenes on several threads may share it.
///
/// Creating a context never touches the GPU; [`Context::gpu`] opens it on first use.
#[derive(Debug, Default)]
pub struct Context {
    options: ContextOptions,
    #[cfg(feature = "gpu")]
    gpu: Mutex<Option<Arc<crate::render::GpuContext>>>,
    #[cfg(not(feature = "gpu"))]
    gpu: Mutex<()>,
    /// The renderer's pipelines, compiled once per device and shared by every scene.
    #[cfg(all(feature = "gpu", feature = "gltf"))]
    renderer: Mutex<Option<Arc<crate::render::Renderer>>>,
}

impl Context {
    /// A context with these options.
    ///
    /// # Errors
    /// `InvalidArgument` for a zero pixel cap.
    pub fn new(options: ContextOptions) -> Result<Self> {
        if options.limits.max_pixels == 0 {
            return Err(crate::Error::invalid("max_image_pixels must be > 0"));
        }
        Ok(Context {
            options,
            gpu: Mutex::default(),
            #[cfg(all(feature = "gpu", feature = "gltf"))]
            renderer: Mutex::default(),
        })
    }

    /// The options it was made with.
    pub fn options(&self) -> &ContextOptions {
        &self.options
    }

    /// Image size caps.
    pub fn limits(&self) -> ImageLimits {
        self.options.limits
    }

    /// The GPU, opened on the first call and shared afterwards. A failed attempt is not cached,
    /// so a host that installs a driver can try again.
    ///
    /// # Errors
    /// `Gpu` when no adapter exists or the device cannot be opened.
    #[cfg(feature = "gpu")]
    pub fn gpu(&self) -> Result<Arc<crate::render::GpuContext>> {
        let mut slot = self
            .gpu
            .lock()
            .map_err(|_| Error::Internal("GPU context lock poisoned by an earlier panic".into()))?;
        if let Some(gpu) = slot.as_ref() {
            return Ok(Arc::clone(gpu));
        }
        let gpu = Arc::new(crate::render::GpuContext::new(
            &crate::render::GpuOptions {
                adapter_name: self.options.adapter_name.clone(),
            },
        )?);
        *slot = Some(Arc::clone(&gpu));
        Ok(gpu)
    }

    /// The renderer on [`Context::gpu`], its shaders and pipelines compiled on the first call and
    /// shared afterwards (by every scene of the context, on any thread). The flag says whether
    /// this call compiled them. A failure is not cached.
    ///
    /// # Errors
    /// As [`Context::gpu`] and [`crate::render::Renderer::new`].
    #[cfg(all(feature = "gpu", feature = "gltf"))]
    pub fn renderer(&self) -> Result<(Arc<crate::render::Renderer>, bool)> {
        let mut slot = self
            .renderer
            .lock()
            .map_err(|_| Error::Internal("renderer lock poisoned by an earlier panic".into()))?;
        if let Some(renderer) = slot.as_ref() {
            return Ok((Arc::clone(renderer), false));
        }
        let renderer = Arc::new(crate::render::Renderer::new(&*self.gpu()?)?);
        *slot = Some(Arc::clone(&renderer));
        Ok((renderer, true))
    }

    /// Whether the GPU has been opened (for tests and traces: creating a context must not open it).
    pub fn gpu_is_open(&self) -> bool {
        #[cfg(feature = "gpu")]
        {
            self.gpu.lock().map(|g| g.is_some()).unwrap_or(false)
        }
        #[cfg(not(feature = "gpu"))]
        {
            let _ = &self.gpu;
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn creating_a_context_does_not_open_the_gpu() {
        let c = Context::new(ContextOptions::default()).unwrap();
        assert!(!c.gpu_is_open());
    }

    #[test]
    fn zero_cap_is_rejected() {
        let options = ContextOptions {
            limits: ImageLimits { max_pixels: 0 },
            ..Default::default()
        };
        assert!(Context::new(options).is_err());
    }
}
