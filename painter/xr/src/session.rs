//! The VR session (docs/vr.md): the painter's wgpu device created through
//! OpenXR's Vulkan interop (XR_KHR_vulkan_enable2: the runtime creates the
//! Vulkan instance and device, wgpu-hal adopts them), one swapchain with a
//! layer per eye wrapped as a wgpu texture, and a frame loop paced by
//! xrWaitFrame that ray casts each eye with its own pose and asymmetric
//! field of view and draws it into its layer.
//!
//! The canvas is placed in the room by a similarity transform kept in f64
//! (`Placement`): the runtime's poses (f32 metres) become canvas points in
//! f64, so any zoom of the canvas keeps its precision.
//!
//! macOS has no OpenXR runtime and wgpu has no Vulkan there: the session is
//! not built for it (`run` says so) and the rest is kept type-checked.
#![cfg_attr(target_os = "macos", allow(dead_code, unused_imports))]

use std::ffi::CStr;
use std::path::PathBuf;
use std::time::Instant;

use ash::vk::{self, Handle};
use glam::DVec3;
use octopaint_gpu::{Blit, Gpu, Precision, Renderer};
use octopaint_pipeline::{Engine, Frames, Hooks, Job, OpenDocument, Settings};
use octopaint_tree::lattice::Lattice;
use octopaint_tree::raycast::RayParams;
use octopaint_tree::trace::Camera;
use octopaint_tree::view::DEFAULT_LIGHT;
use openxr as xr;
use wgpu::hal;

use crate::XrError;
use crate::draw::{pass_on, project, same_look, write_side_by_side};
use crate::paint::Live;
use crate::placement::{Bounds, Placement, eye_camera, head_of};

const VIEW_TYPE: xr::ViewConfigurationType = xr::ViewConfigurationType::PRIMARY_STEREO;

/// What a session did.
#[derive(Debug, Default)]
pub struct Report {
    pub frames: u64,
    pub eye_size: [u32; 2],
    pub format: String,
    /// Wall time between successive xrWaitFrame returns (ms): mean, max.
    pub frame_ms: (f64, f64),
    /// GPU work of a frame (both eyes), submit to done (ms): mean.
    pub render_ms: f64,
    /// Dynamic resolution: the share of the eye's width and height cast,
    /// mean and smallest over the frames, and the frames cast still (at
    /// full size).
    pub scale: (f64, f64),
    pub still_frames: u64,
    /// Strokes painted with the controllers.
    pub strokes: u64,
    pub adapter: String,
    /// Why the save at the session's end failed (every completed stroke
    /// is in the journal still).
    pub save_error: Option<String>,
}

pub struct Options {
    pub frames: Option<u64>,
    pub precision: Precision,
    /// Write the last frame's two eyes side by side here (PNG), read back
    /// from the runtime's swapchain image.
    pub capture: Option<PathBuf>,
    /// Scripted controller states that replace the controllers'
    /// (`input::Script`).
    pub script: Option<PathBuf>,
    /// Cast every frame at the eye's full size (no dynamic resolution).
    pub fixed_resolution: bool,
    /// Play this trace's jobs into the document at their pace from the
    /// first frame on (`octopaint_pipeline::play`); `frames` counts on
    /// until every one of them is queued.
    pub play: Option<PathBuf>,
    /// Tests: while this file exists the stroke thread waits before each
    /// level of painting.
    pub hold_painting: Option<PathBuf>,
}

/// The time both eyes' ray casts aim at: one frame of a 90 Hz headset.
pub const TARGET_FRAME_MS: f64 = 11.1;

fn xr_call<T>(what: &'static str, r: Result<T, xr::sys::Result>) -> Result<T, XrError> {
    crate::call(what, r)
}

fn other(what: &str, e: impl std::fmt::Display) -> XrError {
    XrError::Setup(format!("{what}: {e}"))
}

/// macOS: no VR (crate::platform::NO_VR_HERE says why).
#[cfg(target_os = "macos")]
pub fn run(_doc: octopaint_doc::Session, _opts: &Options) -> Result<Report, XrError> {
    Err(XrError::Unsupported(crate::platform::NO_VR_HERE))
}

/// Run a VR session on the document `doc` until the runtime ends it or
/// `frames` frames have been shown, then save it. The frame loop is the
/// render thread of the real-time engine (docs/architecture.md): the
/// controllers' strokes and layer operations are jobs for its stroke
/// thread, which owns the document, and each frame uploads what was
/// staged and casts both eyes; nothing on the frame's thread waits for
/// painting or saving. Refused before the engine starts (no runtime, no
/// headset), the document is dropped unchanged.
#[cfg(not(target_os = "macos"))]
pub fn run(doc: octopaint_doc::Session, opts: &Options) -> Result<Report, XrError> {
    let mut script = match &opts.script {
        Some(p) => Some(crate::input::Script::load(p)?),
        None => None,
    };
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
        return Err(XrError::Setup(format!("the runtime needs Vulkan {} to {}, the painter uses 1.1", reqs.min_api_version_supported, reqs.max_api_version_supported)));
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
        let phys = vk::PhysicalDevice::from_raw(
            xr_call("finding the headset's GPU", xr_instance.vulkan_graphics_device(system, ash_instance.handle().as_raw() as _))? as _,
        );
        let exposed = hal_instance.expose_adapter(phys).ok_or_else(|| XrError::Setup("the headset's GPU cannot run wgpu".into()))?;
        let mut features = wgpu::Features::empty();
        if opts.precision == Precision::F16 {
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
            xr_instance.create_vulkan_device(system, std::mem::transmute(vk_entry.static_fn().get_instance_proc_addr), phys.as_raw() as _, &create as *const _ as *const _),
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
            .create_device_from_hal(open, &wgpu::DeviceDescriptor { label: Some("octopaint vr"), required_features: features, required_limits: limits.clone(), ..Default::default() })
            .map_err(|e| other("opening the wgpu device", e))?;
        let f16 = features.contains(wgpu::Features::SHADER_F16);
        (Gpu { device, queue, info: adapter.get_info(), limits, f16 }, session_info)
    };
    let adapter_name = gpu.describe();
    let mut renderer = Renderer::with_gpu(gpu).map_err(|e| other("the renderer", e))?;

    // SAFETY: the session is made with the instance and device created
    // above for this system, which outlive it (the renderer holds them).
    let (session, mut waiter, mut stream) = unsafe { xr_call("creating the session", xr_instance.create_session::<xr::Vulkan>(system, &session_info))? };
    let stage = xr_call("creating the reference space", session.create_reference_space(xr::ReferenceSpaceType::LOCAL, xr::Posef::IDENTITY))?;
    let controls = crate::input::Controls::new(&xr_instance, &session)?;
    let mut painter = crate::paint::Painter::default();
    if let Some(m) = doc.mirror() {
        painter.mirror = m;
    }
    // Where the painting is placed first, and the lattice the eyes are cast
    // on, before the document goes to the stroke thread.
    let bounds = Bounds::shown(&doc.doc);
    let lattice = Lattice::new(doc.doc.canvas());
    let settings = Settings::new(Camera { eye: [0.0; 3], q: [0.0, 0.0, 0.0, 1.0], fov: [-0.5, 0.5, 0.5, -0.5], size: [64, 64], background: [0.0; 3] });
    let mut last_input = Instant::now();
    let mut head0 = DVec3::ZERO;
    let views = xr_call("reading the views", xr_instance.enumerate_view_configuration_views(system, VIEW_TYPE))?;
    let size = [views[0].recommended_image_rect_width, views[0].recommended_image_rect_height];
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
    let mut swapchain = xr_call(
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
                let hal_dev = renderer.gpu.device.as_hal::<hal::api::Vulkan>().expect("a Vulkan device");
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
                renderer.gpu.device.create_texture_from_hal::<hal::api::Vulkan>(hal_tex, &desc, wgpu::TextureUses::COLOR_TARGET)
            }
        })
        .collect();
    let blit = Blit::new(&renderer.gpu, format);
    let hud_ctx = egui::Context::default();
    let mut hud = egui_wgpu::Renderer::new(&renderer.gpu.device, format, egui_wgpu::RendererOptions::default());
    let mut placement: Option<Placement> = None;

    let mut report = Report { eye_size: size, format: format!("{format:?}"), adapter: adapter_name, ..Default::default() };
    let mut events = xr::EventDataBuffer::new();
    let mut running = false;
    let mut exit_requested = false;
    let mut last_wait: Option<Instant> = None;
    let (mut frame_sum, mut frame_max, mut render_sum) = (0.0f64, 0.0f64, 0.0f64);
    // Dynamic resolution (docs/vr.md): while the view moves, the eyes are
    // cast at `scale` of their size, `scale` following the time both casts
    // take towards TARGET_FRAME_MS; a frame that changes nothing (head,
    // canvas placement, painting, view) is cast at full size.
    let mut scale = 1.0f64;
    let (mut scale_sum, mut scale_min) = (0.0f64, 1.0f64);
    let mut last_look: Option<([xr::Posef; 2], [f64; 8], (bool, bool))> = None;
    let mut to_play = match &opts.play {
        Some(p) => Some(octopaint_pipeline::play::read(p, &doc).map_err(|e| other("the trace to play", e))?),
        None => None,
    };
    let gate = opts.hold_painting.as_ref().map(|_| std::sync::Arc::new(octopaint_pipeline::Gate::default()));
    let engine = Engine::start(Box::new(OpenDocument::new(doc)), &settings, &Hooks { render: None, stroke: gate.clone() });
    let hold = opts.hold_painting.clone().zip(gate).map(|(path, gate)| octopaint_pipeline::play::hold_while(path, gate));
    let mut playing: Option<std::sync::Arc<std::sync::atomic::AtomicBool>> = None;
    let mut frames = Frames::new(&engine, &settings);
    let mut status = engine.status();
    // The answer to "frame the painting" (X with the left grip), when asked.
    let mut reframing: Option<std::sync::mpsc::Receiver<Bounds>> = None;
    let result = (|| -> Result<(), XrError> {
    'frames: loop {
        while let Some(ev) = xr_call("polling events", xr_instance.poll_event(&mut events))? {
            if let xr::Event::SessionStateChanged(e) = ev {
                match e.state() {
                    xr::SessionState::READY => {
                        xr_call("beginning the session", session.begin(VIEW_TYPE))?;
                        running = true;
                    }
                    xr::SessionState::STOPPING => {
                        xr_call("ending the session", session.end())?;
                        running = false;
                    }
                    xr::SessionState::EXITING | xr::SessionState::LOSS_PENDING => break 'frames,
                    _ => {}
                }
            } else if let xr::Event::InstanceLossPending(_) = ev {
                break 'frames;
            }
        }
        if !running {
            std::thread::sleep(std::time::Duration::from_millis(10));
            continue;
        }
        let played = to_play.is_none() && playing.as_ref().is_none_or(|done| done.load(std::sync::atomic::Ordering::Acquire));
        if opts.frames.is_some_and(|n| report.frames >= n) && played && !exit_requested {
            xr_call("requesting the end", session.request_exit())?;
            exit_requested = true;
        }
        let state = xr_call("waiting for the frame", waiter.wait())?;
        if let Some(t) = last_wait {
            let ms = t.elapsed().as_secs_f64() * 1e3;
            frame_sum += ms;
            frame_max = frame_max.max(ms);
        }
        last_wait = Some(Instant::now());
        xr_call("beginning the frame", stream.begin())?;
        if !state.should_render || exit_requested {
            xr_call("ending the frame", stream.end(state.predicted_display_time, blend, &[]))?;
            continue;
        }
        let (_, views) = xr_call("locating the views", session.locate_views(VIEW_TYPE, state.predicted_display_time, &stage))?;
        // The canvas is placed in front of the head where it first is.
        if placement.is_none() {
            let (head, forward) = head_of(&views);
            head0 = head;
            placement = Some(Placement::around(&bounds, head, forward));
        }
        status = engine.status();
        for m in engine.take_messages() {
            eprintln!("octopaint: vr: {m}");
            painter.last_error = Some(m);
        }
        let place = placement.as_mut().expect("set above");
        // The controllers (or the script) change the painting and the
        // canvas's place before the frame is drawn.
        let hands = match script.as_mut() {
            Some(s) => {
                // Real actions are still synced: the runtime sees an
                // application that reads its controllers.
                controls.read(&session, &stage, state.predicted_display_time)?;
                s.at(report.frames, head0)
            }
            None => controls.read(&session, &stage, state.predicted_display_time)?,
        };
        let dt = last_input.elapsed().as_secs_f64();
        last_input = Instant::now();
        painter.update(&hands, place, &Live { engine: &engine, status: &status }, dt);
        if std::mem::take(&mut painter.reframe) {
            // Frame the painting: asked of the stroke thread, placed in
            // front of the head where it is when the answer comes.
            let (tx, rx) = std::sync::mpsc::channel();
            if engine
                .ask(move |c| {
                    let _ = tx.send(Bounds::shown(c.document()));
                })
                .is_ok()
            {
                reframing = Some(rx);
            }
        }
        if let Some(b) = reframing.as_ref().and_then(|rx| rx.try_recv().ok()) {
            let (head, forward) = head_of(&views);
            *place = Placement::around(&b, head, forward);
            reframing = None;
        }
        let busy_ms = engine.busy().map_or(0.0, |b| b.since.elapsed().as_secs_f64() * 1e3);
        let placement = *place;
        let in_stroke = painter.in_stroke;
        // What the frame uploads: what the engine staged, into each
        // layer's range of the pages.
        let prepared = frames.prepare(&mut renderer).map_err(|e| other("uploading", e))?;
        let (uploaded, table) = (prepared.changed, prepared.layers);
        let (cells, capacity, bytes) = (status.used.min(u64::from(u32::MAX)) as u32, status.capacity, status.bytes);
        let layer_rows = (status.version == 2).then(|| (status.layers.iter().map(|l| (l.name.clone(), l.visible, l.opacity, l.locked)).collect::<Vec<_>>(), status.selected));
        let image = xr_call("acquiring the image", swapchain.acquire_image())? as usize;
        xr_call("waiting for the image", swapchain.wait_image(xr::Duration::INFINITE))?;
        let t0 = Instant::now();
        let mut captured = Vec::new();
        let still;
        {
        let look = (
            [views[0].pose, views[1].pose],
            [placement.centre.x, placement.centre.y, placement.centre.z, placement.scale, placement.rotation.x, placement.rotation.y, placement.rotation.z, placement.rotation.w],
            painter.lit_and_grid(),
        );
        still = !uploaded && last_look.as_ref().is_some_and(|l| same_look(l, &look));
        last_look = Some(look);
        let now_scale = if still || opts.fixed_resolution { 1.0 } else { scale };
        let cast = size.map(|v| ((f64::from(v) * now_scale).round() as u32).clamp(1, v));
        scale_sum += now_scale;
        scale_min = scale_min.min(now_scale);
        report.still_frames += u64::from(still);
        let gpu = &renderer.gpu;
        // The indicators, head-locked; the palette at the left hand,
        // where each eye sees it.
        let depth = lattice.target_depth(painter.room_radius / placement.scale);
        // The canvas axes as the head sees them (the first eye's pose).
        let axes = octopaint_tree::view::axes_seen_from(placement.rotate_to_canvas(crate::pose_of(&views[0].pose).1));
        let status = crate::hud::Status {
            busy_ms,
            in_stroke,
            cells,
            capacity,
            bytes,
            painter: &painter,
            canvas_per_metre: 1.0 / placement.scale,
            depth,
            edge: lattice.size_canvas[depth as usize],
            axes,
            layers: layer_rows,
        };
        let mut hud_free = Vec::new();
        let capture_now = opts.capture.is_some() && opts.frames.is_some_and(|n| report.frames + 1 == n);
        for (eye, view) in views.iter().enumerate() {
            let camera = eye_camera(&placement, view, cast);
            let (lit, grid) = painter.lit_and_grid();
            let mut params = RayParams::new(&lattice, &camera).with_light(lit.then_some(&DEFAULT_LIGHT));
            if grid {
                params = params.with_grid(camera.eye);
            }
            let mut enc = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("eye") });
            match &table {
                Some(t) => renderer.ray.encode_layers(gpu, &renderer.pools, &mut enc, &params, opts.precision, t),
                None => renderer.ray.encode(gpu, &renderer.pools, &mut enc, &params, opts.precision),
            }
            .map_err(|e| other("ray casting", e))?;
            let group = blit.bind_scaled(gpu, renderer.ray.pixel_buffer().expect("cast above"), cast, size);
            let target = textures[image].create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: eye as u32,
                array_layer_count: Some(1),
                ..Default::default()
            });
            {
                let mut pass = pass_on(&mut enc, &target, wgpu::LoadOp::Clear(wgpu::Color::BLACK));
                blit.draw(&mut pass, &group);
            }
            {
                // Only where the eye sees the hand: egui would pull a panel
                // placed off the image back onto its edge.
                let seen = |q: [f32; 2]| (0.0..size[0] as f32).contains(&q[0]) && (0.0..size[1] as f32).contains(&q[1]);
                let palette_at = hands[crate::input::LEFT].pose.and_then(|(p, _)| project(view, size, p)).filter(|&q| seen(q));
                // The brush's ghost at the right controller's tip, where
                // this eye sees it, as wide as the brush there.
                let cursor = hands[crate::input::RIGHT].pose.and_then(|(p, _)| {
                    let centre = project(view, size, p)?;
                    let eye = crate::pose_of(&view.pose).1;
                    let edge = project(view, size, p + eye * DVec3::X * painter.room_radius)?;
                    Some((centre, (edge[0] - centre[0]).hypot(edge[1] - centre[1])))
                });
                let (hud_jobs, hud_screen, free) = crate::hud::prepare(&hud_ctx, &mut hud, gpu, size, &status, palette_at, cursor);
                hud_free.extend(free);
                hud.update_buffers(&gpu.device, &gpu.queue, &mut enc, &hud_jobs, &hud_screen);
                let mut pass = pass_on(&mut enc, &target, wgpu::LoadOp::Load).forget_lifetime();
                hud.render(&mut pass, &hud_jobs, &hud_screen);
            }
            if capture_now {
                // The eye's layer of the runtime's image as drawn, then the
                // layer back in the colour-attachment layout the runtime
                // expects at release (an empty pass that loads and stores).
                let row = (size[0] * 4).div_ceil(256) * 256;
                let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("capture"),
                    size: u64::from(row) * u64::from(size[1]),
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                enc.copy_texture_to_buffer(
                    wgpu::TexelCopyTextureInfo { texture: &textures[image], mip_level: 0, origin: wgpu::Origin3d { x: 0, y: 0, z: eye as u32 }, aspect: wgpu::TextureAspect::All },
                    wgpu::TexelCopyBufferInfo { buffer: &buf, layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: None } },
                    wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 },
                );
                drop(pass_on(&mut enc, &target, wgpu::LoadOp::Load));
                gpu.queue.submit([enc.finish()]);
                let raw = octopaint_gpu::pools::read_buffer(gpu, &buf, u64::from(row) * u64::from(size[1])).map_err(|e| other("reading back", e))?;
                captured.push(octopaint_gpu::image::texels_to_rgb(&raw, row, size, format));
            } else {
                gpu.queue.submit([enc.finish()]);
            }
        }
        gpu.wait();
        frames.ended(Instant::now());
        for id in &hud_free {
            hud.free_texture(id);
        }
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        render_sum += ms;
        if !still && !opts.fixed_resolution {
            scale = octopaint_tree::view::follow_frame_time(scale, ms, TARGET_FRAME_MS);
        }
        xr_call("releasing the image", swapchain.release_image())?;
        let rect = xr::Rect2Di { offset: xr::Offset2Di { x: 0, y: 0 }, extent: xr::Extent2Di { width: size[0] as i32, height: size[1] as i32 } };
        let proj: Vec<xr::CompositionLayerProjectionView<xr::Vulkan>> = (0..2)
            .map(|eye| {
                xr::CompositionLayerProjectionView::new()
                    .pose(views[eye].pose)
                    .fov(views[eye].fov)
                    .sub_image(xr::SwapchainSubImage::new().swapchain(&swapchain).image_array_index(eye as u32).image_rect(rect))
            })
            .collect();
        xr_call(
            "ending the frame",
            stream.end(state.predicted_display_time, blend, &[&xr::CompositionLayerProjection::new().space(&stage).views(&proj)]),
        )?;
        report.frames += 1;
        if let Some(jobs) = to_play.take() {
            playing = Some(octopaint_pipeline::play::start(engine.submitter(), jobs));
        }
        if let (Some(path), true) = (&opts.capture, captured.len() == 2) {
            write_side_by_side(path, &captured, size).map_err(|e| other("writing the capture", e))?;
        }
    }
    Ok(())
    })();
    // The session's end: a test's hold lets go, the open stroke ends, and
    // the document is saved on the stroke thread; ending waits for it, and
    // says so.
    if let Some(stop) = &hold {
        stop.store(true, std::sync::atomic::Ordering::Release);
    }
    painter.finish(&Live { engine: &engine, status: &status });
    let _ = engine.submit(Job::Save);
    eprintln!("octopaint: vr: saving the document…");
    let finished = engine.finish().map_err(|e| other("the engine", e))?;
    for m in finished.messages {
        if m.starts_with("save failed") {
            report.save_error = Some(m);
        } else {
            eprintln!("octopaint: vr: {m}");
        }
    }
    result?;
    report.strokes = painter.strokes;
    if let Some(e) = &painter.last_error {
        eprintln!("octopaint: vr: an input event was refused: {e}");
    }
    if report.frames > 1 {
        report.frame_ms = (frame_sum / (report.frames - 1) as f64, frame_max);
    }
    if report.frames > 0 {
        report.render_ms = render_sum / report.frames as f64;
        report.scale = (scale_sum / report.frames as f64, scale_min);
    }
    drop(textures);
    drop(swapchain);
    drop(stage);
    drop((session, waiter, stream));
    Ok(report)
}
