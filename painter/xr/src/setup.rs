//! Setting a VR session up (docs/vr.md): the OpenXR instance and the
//! headset, the painter's wgpu device created through OpenXR's Vulkan
//! interop (XR_KHR_vulkan_enable2: the runtime creates the Vulkan
//! instance and device, wgpu-hal adopts them), and one swapchain with a
//! layer per eye wrapped as wgpu textures.
#![cfg_attr(target_os = "macos", allow(dead_code, unused_imports))]

use std::ffi::CStr;

use ash::vk::{self, Handle};
use octopaint_gpu::{Gpu, Precision};
use openxr as xr;
use wgpu::hal;

use crate::XrError;

pub(crate) const VIEW_TYPE: xr::ViewConfigurationType = xr::ViewConfigurationType::PRIMARY_STEREO;

pub(crate) fn xr_call<T>(what: &'static str, r: Result<T, xr::sys::Result>) -> Result<T, XrError> {
    crate::call(what, r)
}

pub(crate) fn other(what: &str, e: impl std::fmt::Display) -> XrError {
    XrError::Setup(format!("{what}: {e}"))
}

/// The runtime, the headset and the GPU the session renders with.
pub(crate) struct Opened {
    pub xr_instance: xr::Instance,
    pub system: xr::SystemId,
    pub blend: xr::EnvironmentBlendMode,
    pub gpu: Gpu,
    pub session_info: xr::vulkan::SessionCreateInfo,
}

/// Find the runtime and the headset, and open the headset's GPU for wgpu
/// (with SHADER_F16 for `precision` f16).
#[cfg(not(target_os = "macos"))]
pub(crate) fn open(precision: Precision) -> Result<Opened, XrError> {
    // SAFETY: see crate::probe.
    let entry = unsafe { xr::Entry::load(&()) }.map_err(|e| XrError::NoLoader(e.to_string()))?;
    let available = xr_call("enumerating extensions", entry.enumerate_extensions())?;
    if !available.khr_vulkan_enable2 {
        return Err(XrError::Setup(format!(
            "the runtime has no XR_KHR_vulkan_enable2, the only graphics binding the painter renders through{}",
            crate::platform::NO_VULKAN_BINDING_HELP
        )));
    }
    let mut exts = xr::ExtensionSet::default();
    exts.khr_vulkan_enable2 = true;
    let xr_instance = crate::create_instance(&entry, &exts)?;
    let system = xr_call("finding the headset", xr_instance.system(xr::FormFactor::HEAD_MOUNTED_DISPLAY))?;
    let blend = xr_call("reading blend modes", xr_instance.enumerate_environment_blend_modes(system, VIEW_TYPE))?[0];
    let reqs = xr_call("reading the Vulkan requirements", xr_instance.graphics_requirements::<xr::Vulkan>(system))?;
    let want = xr::Version::new(1, 1, 0);
    if want < reqs.min_api_version_supported || want.major() > reqs.max_api_version_supported.major() {
        return Err(XrError::Setup(format!(
            "the runtime needs Vulkan {} to {}, the painter uses 1.1",
            reqs.min_api_version_supported, reqs.max_api_version_supported
        )));
    }

    // SAFETY (this block): Vulkan objects are created by the runtime from
    // create infos that live across each call; the raw handles are given
    // to wgpu-hal, which owns them from then on (it destroys the device and
    // instance when the last wgpu handle goes), and to the OpenXR session,
    // which the runtime requires to be the same ones.
    let (gpu, session_info) = unsafe {
        let vk_entry = ash::Entry::load().map_err(|e| other("loading Vulkan", e))?;
        let flags = wgpu::InstanceFlags::empty();
        // The newest Vulkan the loader offers, up to 1.3: wgpu-hal calls
        // 1.2 core functions (timeline semaphores) when the device has
        // them, which the instance must then have been created for.
        let loader = vk_entry.try_enumerate_instance_version().ok().flatten().unwrap_or(vk::make_api_version(0, 1, 0, 0));
        let api = loader.min(vk::make_api_version(0, 1, 3, 0));
        if api < vk::make_api_version(0, 1, 1, 0) {
            return Err(XrError::Setup("the Vulkan loader is older than 1.1".into()));
        }
        let extensions = hal::vulkan::Instance::desired_extensions(&vk_entry, api, flags).map_err(|e| other("Vulkan instance extensions", e))?;
        let ext_ptrs: Vec<*const std::ffi::c_char> = extensions.iter().map(|e| e.as_ptr()).collect();
        let app = vk::ApplicationInfo::default().application_name(c"octopaint").api_version(api);
        let create = vk::InstanceCreateInfo::default().application_info(&app).enabled_extension_names(&ext_ptrs);
        #[allow(clippy::missing_transmute_annotations)]
        let raw_instance = xr_call(
            "creating the Vulkan instance",
            xr_instance.create_vulkan_instance(system, std::mem::transmute(vk_entry.static_fn().get_instance_proc_addr), &create as *const _ as *const _),
        )?
        .map_err(|e| other("creating the Vulkan instance", vk::Result::from_raw(e)))?;
        let ash_instance = ash::Instance::load(vk_entry.static_fn(), vk::Instance::from_raw(raw_instance as _));
        let hal_instance = hal::vulkan::Instance::from_raw(
            vk_entry.clone(),
            ash_instance.clone(),
            api,
            0,
            None,
            extensions,
            flags,
            wgpu::MemoryBudgetThresholds::default(),
            false,
            None,
        )
        .map_err(|e| other("adopting the Vulkan instance", e))?;
        let phys = vk::PhysicalDevice::from_raw(xr_call(
            "finding the headset's GPU",
            xr_instance.vulkan_graphics_device(system, ash_instance.handle().as_raw() as _),
        )? as _);
        let exposed = hal_instance.expose_adapter(phys).ok_or_else(|| XrError::Setup("the headset's GPU cannot run wgpu".into()))?;
        let mut features = wgpu::Features::empty();
        if precision == Precision::F16 {
            if !exposed.features.contains(wgpu::Features::SHADER_F16) {
                return Err(XrError::Setup("the headset's GPU has no SHADER_F16 for --precision f16".into()));
            }
            features |= wgpu::Features::SHADER_F16;
        }
        let limits = exposed.capabilities.limits.clone();
        let dev_exts = exposed.adapter.required_device_extensions(features);
        let dev_ext_ptrs: Vec<*const std::ffi::c_char> = dev_exts.iter().map(|e: &&CStr| e.as_ptr()).collect();
        let mut phd_features = exposed.adapter.physical_device_features(&dev_exts, features);
        let family = ash_instance
            .get_physical_device_queue_family_properties(phys)
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE))
            .ok_or_else(|| XrError::Setup("the headset's GPU has no graphics and compute queue".into()))? as u32;
        let priorities = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default().queue_family_index(family).queue_priorities(&priorities)];
        let create = vk::DeviceCreateInfo::default().queue_create_infos(&queues).enabled_extension_names(&dev_ext_ptrs);
        let create = phd_features.add_to_device_create(create);
        #[allow(clippy::missing_transmute_annotations)]
        let raw_device = xr_call(
            "creating the Vulkan device",
            xr_instance.create_vulkan_device(
                system,
                std::mem::transmute(vk_entry.static_fn().get_instance_proc_addr),
                phys.as_raw() as _,
                &create as *const _ as *const _,
            ),
        )?
        .map_err(|e| other("creating the Vulkan device", vk::Result::from_raw(e)))?;
        let ash_device = ash::Device::load(ash_instance.fp_v1_0(), vk::Device::from_raw(raw_device as _));
        let device_handle = ash_device.handle();
        let open = exposed
            .adapter
            .device_from_raw(ash_device, None, &dev_exts, features, &limits, &wgpu::MemoryHints::Performance, family, 0)
            .map_err(|e| other("adopting the Vulkan device", e))?;
        let session_info = xr::vulkan::SessionCreateInfo {
            instance: ash_instance.handle().as_raw() as _,
            physical_device: phys.as_raw() as _,
            device: device_handle.as_raw() as _,
            queue_family_index: family,
            queue_index: 0,
        };
        let instance = wgpu::Instance::from_hal::<hal::api::Vulkan>(hal_instance);
        let adapter = instance.create_adapter_from_hal(exposed);
        let (device, queue) = adapter
            .create_device_from_hal(
                open,
                &wgpu::DeviceDescriptor { label: Some("octopaint vr"), required_features: features, required_limits: limits.clone(), ..Default::default() },
            )
            .map_err(|e| other("opening the wgpu device", e))?;
        let f16 = features.contains(wgpu::Features::SHADER_F16);
        (Gpu { device, queue, info: adapter.get_info(), limits, f16 }, session_info)
    };
    Ok(Opened { xr_instance, system, blend, gpu, session_info })
}

/// The swapchain both eyes are drawn into: one image of two array layers
/// per frame, each wrapped as a wgpu texture.
pub(crate) struct Eyes {
    pub swapchain: xr::Swapchain<xr::Vulkan>,
    pub textures: Vec<wgpu::Texture>,
    /// Each eye's image size (the runtime's recommended size).
    pub size: [u32; 2],
    pub format: wgpu::TextureFormat,
}

impl Eyes {
    #[cfg(not(target_os = "macos"))]
    pub(crate) fn create(session: &xr::Session<xr::Vulkan>, gpu: &Gpu, size: [u32; 2]) -> Result<Eyes, XrError> {
        let formats = xr_call("reading swapchain formats", session.enumerate_swapchain_formats())?;
        // Unorm first (the cast bytes are sRGB already), sRGB next (decoded
        // in the blit, encoded again by the hardware).
        let choice = [
            (vk::Format::R8G8B8A8_UNORM, wgpu::TextureFormat::Rgba8Unorm),
            (vk::Format::B8G8R8A8_UNORM, wgpu::TextureFormat::Bgra8Unorm),
            (vk::Format::R8G8B8A8_SRGB, wgpu::TextureFormat::Rgba8UnormSrgb),
            (vk::Format::B8G8R8A8_SRGB, wgpu::TextureFormat::Bgra8UnormSrgb),
        ]
        .into_iter()
        .find(|(vkf, _)| formats.contains(&(vkf.as_raw() as u32)))
        .ok_or_else(|| XrError::Setup(format!("no 8-bit RGBA swapchain format among the runtime's {formats:?}")))?;
        let (vk_format, format) = choice;
        let swapchain = xr_call(
            "creating the swapchain",
            session.create_swapchain(&xr::SwapchainCreateInfo {
                create_flags: xr::SwapchainCreateFlags::EMPTY,
                usage_flags: xr::SwapchainUsageFlags::COLOR_ATTACHMENT | xr::SwapchainUsageFlags::TRANSFER_SRC,
                format: vk_format.as_raw() as _,
                sample_count: 1,
                width: size[0],
                height: size[1],
                face_count: 1,
                array_size: 2,
                mip_count: 1,
            }),
        )?;
        let images = xr_call("reading the swapchain images", swapchain.enumerate_images())?;
        let desc = wgpu::TextureDescriptor {
            label: Some("xr swapchain"),
            size: wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 2 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        };
        let textures: Vec<wgpu::Texture> = images
            .iter()
            .map(|&img| {
                // SAFETY: the image belongs to the runtime's swapchain, lives as
                // long as it, and is only drawn between acquire and release. It
                // is not wgpu's: External memory, and a drop callback, which
                // tells wgpu-hal not to destroy the image (without one it does,
                // and the runtime's own destroy is then a double free).
                unsafe {
                    let hal_dev = gpu.device.as_hal::<hal::api::Vulkan>().expect("a Vulkan device");
                    let hal_tex = hal_dev.texture_from_raw(
                        vk::Image::from_raw(img),
                        &hal::TextureDescriptor {
                            label: Some("xr swapchain"),
                            size: desc.size,
                            mip_level_count: 1,
                            sample_count: 1,
                            dimension: wgpu::TextureDimension::D2,
                            format,
                            usage: wgpu::TextureUses::COLOR_TARGET | wgpu::TextureUses::COPY_SRC,
                            memory_flags: hal::MemoryFlags::empty(),
                            view_formats: vec![],
                        },
                        Some(Box::new(|| {})),
                        hal::vulkan::TextureMemory::External,
                    );
                    drop(hal_dev);
                    gpu.device.create_texture_from_hal::<hal::api::Vulkan>(hal_tex, &desc, wgpu::TextureUses::COLOR_TARGET)
                }
            })
            .collect();
        Ok(Eyes { swapchain, textures, size, format })
    }
}
