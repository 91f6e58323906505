//! The adapter and the device. A machine without an adapter is an error
//! with a message saying what to install, never a silent fallback: the
//! tests that need a GPU fail on such a machine rather than skip.

use crate::shaders::Precision;

/// Which graphics API to run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// Vulkan if an adapter has it, else OpenGL.
    Auto,
    Vulkan,
    Gl,
}

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no {0} adapter found ({ADAPTER_HELP})")]
    NoAdapter(&'static str),
    #[error("the GPU refused a device: {0}")]
    Device(#[from] wgpu::RequestDeviceError),
    #[error("the adapter's largest storage binding ({0} bytes) is below one page of 65,536 cells")]
    BindingTooSmall(u64),
    #[error("the tree has {cells} cells; this GPU holds at most {max} ({pages} pages of {page} cells)")]
    Capacity { cells: u64, max: u64, pages: u32, page: u64 },
    #[error("this adapter has no SHADER_F16: the f16 ray caster needs it")]
    NoF16,
    #[error("reading back from the GPU failed: {0}")]
    Readback(String),
    #[error("too big for this GPU: {0}")]
    TooBig(String),
}

/// What to install when no adapter is found.
#[cfg(windows)]
const ADAPTER_HELP: &str = "install or update the GPU vendor's driver (NVIDIA, AMD, Intel): it brings Vulkan";
#[cfg(not(windows))]
const ADAPTER_HELP: &str = "on Debian: apt-get install mesa-vulkan-drivers libvulkan1 for Vulkan, libegl1 libegl-mesa0 libgl1-mesa-dri for GL";

/// Seconds of `f` for benchmarks: the median of `runs` runs after a
/// warm-up of at least one run and 0.3 s. A GPU left idle (while the CPU
/// staged a big tree, say) drops its clocks and takes a moment to raise
/// them: on an H100 a first cast at idle clocks took 3.4 times as long as
/// the same cast warm.
pub fn warm_median<E>(runs: usize, mut f: impl FnMut() -> Result<(), E>) -> Result<f64, E> {
    let warm = std::time::Instant::now();
    f()?;
    while warm.elapsed().as_secs_f64() < 0.3 {
        f()?;
    }
    let mut v = Vec::with_capacity(runs.max(1));
    for _ in 0..runs.max(1) {
        let t = std::time::Instant::now();
        f()?;
        v.push(t.elapsed().as_secs_f64());
    }
    v.sort_by(|a, b| a.total_cmp(b));
    Ok(v[v.len() / 2])
}

/// What [`Gpu::bandwidth`] measured.
#[derive(Clone, Copy, Debug)]
pub struct Bandwidth {
    pub bytes: u64,
    pub copy_seconds: f64,
    pub write_seconds: f64,
    pub empty_seconds: f64,
}

/// A device and its queue, with what the pipeline needs to know of the
/// adapter.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    pub f16: bool,
}

impl Gpu {
    /// Open the first adapter of `backend`.
    pub fn open(backend: Backend) -> Result<Gpu, GpuError> {
        let backends = match backend {
            Backend::Auto => wgpu::Backends::VULKAN | wgpu::Backends::GL,
            Backend::Vulkan => wgpu::Backends::VULKAN,
            Backend::Gl => wgpu::Backends::GL,
        };
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = backends;
        let instance = wgpu::Instance::new(desc);
        let mut adapters = pollster::block_on(instance.enumerate_adapters(backends));
        // Vulkan first (it has SHADER_F16 on lavapipe; GL does not), then
        // discrete before integrated before CPU.
        adapters.sort_by_key(|a| {
            let i = a.get_info();
            let api = if i.backend == wgpu::Backend::Vulkan { 0 } else { 1 };
            let kind = match i.device_type {
                wgpu::DeviceType::DiscreteGpu => 0,
                wgpu::DeviceType::IntegratedGpu => 1,
                wgpu::DeviceType::VirtualGpu => 2,
                wgpu::DeviceType::Cpu => 3,
                wgpu::DeviceType::Other => 4,
            };
            (api, kind)
        });
        let name = match backend {
            Backend::Auto => "Vulkan or GL",
            Backend::Vulkan => "Vulkan",
            Backend::Gl => "GL",
        };
        let adapter = adapters.into_iter().next().ok_or(GpuError::NoAdapter(name))?;
        Gpu::from_adapter(&adapter)
    }

    /// A device on `adapter` (a window chooses the adapter that can
    /// present to its surface), with the features and limits the pipeline
    /// uses.
    pub fn from_adapter(adapter: &wgpu::Adapter) -> Result<Gpu, GpuError> {
        let f16 = adapter.features().contains(wgpu::Features::SHADER_F16);
        let limits = adapter.limits();
        let mut required_features = wgpu::Features::empty();
        if f16 {
            required_features |= wgpu::Features::SHADER_F16;
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("octopaint"),
            required_features,
            required_limits: limits.clone(),
            ..Default::default()
        }))?;
        Ok(Gpu { device, queue, info: adapter.get_info(), limits, f16 })
    }

    /// Whether the ray caster can run in `precision` here.
    pub fn supports(&self, precision: Precision) -> bool {
        precision == Precision::F32 || self.f16
    }

    /// A line naming the adapter, for logs and reports.
    pub fn describe(&self) -> String {
        format!("{} ({:?}, {:?}, driver {})", self.info.name, self.info.backend, self.info.device_type, self.info.driver_info)
    }

    /// The layout of a pass's own bindings: a uniform block at binding 0
    /// and one storage buffer at binding 1 (the g3 pass's mask, the ray
    /// caster's pixels, the blit's pixels).
    pub fn params_layout(&self, label: &str, visibility: wgpu::ShaderStages, storage_read_only: bool) -> wgpu::BindGroupLayout {
        self.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility,
                    ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: storage_read_only },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        })
    }

    /// The device's own bandwidth, for uploads to be judged against
    /// (benchmarks): seconds of a copy of `bytes` between two buffers on
    /// the GPU, of a `write_buffer` of `bytes` from the host, and of an
    /// empty submit-and-wait; each the median of `runs` after a warm-up.
    pub fn bandwidth(&self, bytes: u64, runs: usize) -> Bandwidth {
        let make = |label| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let (src, dst) = (make("bandwidth source"), make("bandwidth destination"));
        let copy_seconds = warm_median(runs, || {
            let mut enc = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bandwidth") });
            enc.copy_buffer_to_buffer(&src, 0, &dst, 0, bytes);
            self.queue.submit([enc.finish()]);
            self.wait();
            Ok::<(), std::convert::Infallible>(())
        });
        let host: Vec<u8> = (0..bytes).map(|i| (i.wrapping_mul(7) + 3) as u8).collect();
        let write_seconds = warm_median(runs, || {
            self.queue.write_buffer(&dst, 0, &host);
            self.queue.submit([]);
            self.wait();
            Ok(())
        });
        let empty_seconds = warm_median(runs.max(20), || {
            self.queue.submit([]);
            self.wait();
            Ok(())
        });
        let never = |e: std::convert::Infallible| match e {};
        Bandwidth {
            bytes,
            copy_seconds: copy_seconds.unwrap_or_else(never),
            write_seconds: write_seconds.unwrap_or_else(never),
            empty_seconds: empty_seconds.unwrap_or_else(never),
        }
    }

    /// Block until the GPU has done everything submitted so far.
    pub fn wait(&self) {
        let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
    }
}
