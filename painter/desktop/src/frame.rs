//! One frame of the window (docs/desktop.md): take what the engine staged
//! (uploads into each layer's range, g3 per layer: `Frames::prepare`),
//! cast the view at the resolution dynamic resolution chose (or, when
//! nothing changed and the last cast was the still view at full size, cast
//! nothing and present it again), draw the panel over it, present, and
//! tell the ledger. Nothing here touches the tree or the document.

use std::time::{Duration, Instant};

use octopaint_gpu::image::Capture;
use octopaint_pipeline::{Doing, Frames, Indicator};
use octopaint_tree::raycast::RayParams;
use octopaint_tree::view::BACKGROUND;

use crate::app::App;
use crate::overlay::Overlay;
use crate::panel::{LayerInfo, StatusInfo, panel};

impl App {
    /// The heavy-operation indicator's text and progress: the close's
    /// save, or the stroke thread busy for a while or work queued.
    fn busy(&self) -> Option<(String, Option<f32>)> {
        let engine = self.engine.as_ref()?;
        if let Some(t) = self.closing {
            return Some((format!("saving before closing… {:.1} s", t.elapsed().as_secs_f64()), None));
        }
        Indicator::of(engine, 50.0).map(|i| (i.text, i.progress))
    }

    pub(crate) fn frame(&mut self) -> Result<(), String> {
        let precision = self.opts.precision;
        let screenshot_path = self.opts.screenshot.clone();
        // What the stroke thread said and published since the last frame.
        if let Some(engine) = &self.engine {
            self.status = engine.status();
            for m in engine.take_messages() {
                self.note(m);
            }
        }
        if let Some(rx) = &self.framed
            && let Ok(cam) = rx.try_recv()
        {
            self.framed = None;
            if let Some(r) = self.running.as_mut() {
                r.camera = octopaint_tree::view::OrbitCamera { covered: r.camera.covered, ..cam };
                r.message = "framed the painting".into();
            }
        }
        let point = self.brush_point();
        let busy = self.busy();
        let doing = self.engine.as_ref().map_or(Doing::Nothing, Doing::of);
        let latency_ms = self.engine.as_ref().and_then(|e| e.last_latency_ms());
        let Some(r) = self.running.as_mut() else { return Ok(()) };
        r.last_frame = Instant::now();
        let prepared = r.frames.prepare(&mut r.renderer).map_err(|e| e.to_string())?;
        let size = [r.config.width, r.config.height];
        let light = r.brush.light.light(r.camera.rotation());
        // A screenshot is always of the full resolution, moving or not.
        let mirror = r.brush.mirror_axes.iter().enumerate().fold(0u8, |m, (a, &on)| m | (u8::from(on) << a));
        let have_cast = r.renderer.ray.pixel_buffer().is_some();
        let planned = r.view.plan(size, (r.camera, size, r.brush.grid, light, r.brush.lod), prepared.changed, r.want_screenshot, have_cast, mirror);
        let cast = planned.size;
        let camera = r.camera.camera(cast, BACKGROUND);
        // The cut follows the size cast (a frame at reduced resolution is
        // a coarser, cheaper one: spec 7).
        let mut params = RayParams::new(&self.lattice, &camera).with_light(light.as_ref()).with_lod(&camera, r.brush.lod);
        if r.brush.grid {
            params = params.with_grid(camera.eye);
        }
        let overlay = Overlay::new(&r.camera, size, r.cursor, &r.brush, &self.lattice, point.expect("running"));
        // The panel.
        let raw = r.egui_state.take_egui_input(&r.window);
        let mut actions = Vec::new();
        let s = &self.status;
        let info = StatusInfo {
            fps: r.view.stats.fps,
            resolution: f64::from(cast[0]) / f64::from(size[0].max(1)),
            latency_ms,
            busy,
            cells: s.used.min(u64::from(u32::MAX)) as u32,
            capacity: s.capacity,
            bytes: s.bytes,
            undo: s.undo,
            redo: s.redo,
            message: r.message.clone(),
            layered: s.version == 2,
            layers: s
                .layers
                .iter()
                .map(|l| LayerInfo { name: l.name.clone(), visible: l.visible, opacity: l.opacity, locked: l.locked, cells: l.cells, bytes: l.bytes })
                .collect(),
            selected: s.selected,
            presets: r.presets.list.iter().map(|p| p.name.clone()).collect(),
        };
        let mut view = None;
        let out = r.egui_ctx.run_ui(raw, |ui| view = Some(panel(ui, &mut r.brush, &mut r.layers, &info, &overlay, &mut actions)));
        // The next frames centre the view on the part the panel leaves.
        if let Some(v) = view {
            r.camera.covered = (f64::from(v.left() * out.pixels_per_point) / f64::from(size[0].max(1))).clamp(0.0, 0.9);
        }
        r.egui_wants = out.viewport_output.get(&egui::ViewportId::ROOT).is_some_and(|v| v.repaint_delay < Duration::from_millis(100));
        r.egui_state.handle_platform_output(&r.window, out.platform_output);
        let jobs = r.egui_ctx.tessellate(out.shapes, out.pixels_per_point);
        let screen = egui_wgpu::ScreenDescriptor { size_in_pixels: size, pixels_per_point: out.pixels_per_point };
        let gpu = &r.renderer.gpu;
        for (id, deltas) in &out.textures_delta.set {
            for delta in deltas {
                r.egui_renderer.update_texture(&gpu.device, &gpu.queue, *id, delta);
            }
        }
        let frame = match r.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f) | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            other => {
                r.surface.configure(&gpu.device, &r.config);
                return if matches!(
                    other,
                    wgpu::CurrentSurfaceTexture::Lost
                        | wgpu::CurrentSurfaceTexture::Outdated
                        | wgpu::CurrentSurfaceTexture::Timeout
                        | wgpu::CurrentSurfaceTexture::Occluded
                ) {
                    Ok(())
                } else {
                    Err("the window's surface failed".into())
                };
            }
        };
        let mut enc = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        // A still view already cast at full size is presented again.
        if planned.cast {
            Frames::encode_cast(&mut r.renderer, &mut enc, &params, precision, &prepared).map_err(|e| e.to_string())?;
        }
        r.view.log(doing, (prepared.upload_seconds + prepared.g3_seconds) * 1e3);
        let gpu = &r.renderer.gpu;
        let pixels = r.renderer.ray.pixel_buffer().expect("cast above");
        let group = r.blit.bind_scaled(gpu, pixels, cast, size);
        r.egui_renderer.update_buffers(&gpu.device, &gpu.queue, &mut enc, &jobs, &screen);
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor::default());
        let shot = r.want_screenshot.then(|| {
            gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("screenshot"),
                size: wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: r.config.format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        });
        let targets: Vec<wgpu::TextureView> = std::iter::once(view).chain(shot.iter().map(|t| t.create_view(&Default::default()))).collect();
        for target in &targets {
            let mut pass = enc
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("window"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: target,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                })
                .forget_lifetime();
            r.blit.draw(&mut pass, &group);
            r.egui_renderer.render(&mut pass, &jobs, &screen);
        }
        let readback = shot.as_ref().map(|t| Capture::encode(gpu, &mut enc, t, 0, size, r.config.format));
        gpu.queue.submit([enc.finish()]);
        r.window.pre_present_notify();
        gpu.queue.present(frame);
        // The frame's end for the ledger: its jobs are shown.
        r.frames.ended(Instant::now());
        for id in &out.textures_delta.free {
            r.egui_renderer.free_texture(id);
        }
        if let Some(capture) = readback {
            r.want_screenshot = false;
            let written = capture
                .rgb(gpu)
                .map_err(|e| e.to_string())
                .and_then(|rgb| octopaint_gpu::image::write_png(&screenshot_path, &rgb, size[0], size[1]).map_err(|e| e.to_string()));
            let msg = match written {
                Ok(()) => format!("wrote {}", screenshot_path.display()),
                Err(e) => format!("screenshot failed: {e}"),
            };
            eprintln!("octopaint: {msg}");
            r.message = msg;
        }
        if let Some(jobs) = self.to_play.take()
            && let Some(engine) = &self.engine
        {
            self.playing = Some(octopaint_pipeline::play::start(engine.submitter(), jobs));
        }
        for a in actions {
            self.act(a);
        }
        Ok(())
    }
}
