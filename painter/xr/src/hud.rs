//! The headset's indicators and palette (the paper's §8.3 asks for a
//! heavy-operation indicator and a memory-budget indicator): an egui panel
//! drawn over both eyes' images at the same place (head-locked), and the
//! palette drawn where each eye sees the left controller (so it sits at
//! the controller's depth).

use octopaint_pipeline::LayerRow;
use octopaint_tree::trace::{Mode, Shape};

use crate::gestures::{Gestures, PAGES, PALETTE, Page};

pub struct Status<'a> {
    /// The heavy-operation indicator, when the stroke thread has been busy
    /// for a frame or more or work is queued.
    pub busy: Option<octopaint_pipeline::Indicator>,
    pub in_stroke: bool,
    pub cells: u32,
    pub capacity: u32,
    pub bytes: usize,
    pub painter: &'a Gestures,
    /// Canvas units in one metre of the room (the zoom), the depth the
    /// brush paints at and that depth's cell edge (canvas units).
    pub canvas_per_metre: f64,
    pub depth: u32,
    pub edge: f64,
    /// The canvas axes x, y, z as the head sees them: direction on the
    /// panel (y down) and whether the axis points away.
    pub axes: [([f32; 2], bool); 3],
    /// The document's layers bottom first, as the stroke thread published
    /// them, and the selected one; None for a one-tree document.
    pub layers: Option<(&'a [LayerRow], usize)>,
}

/// Lay the panel out for a `size` eye image and upload its textures;
/// returns what `egui_wgpu::Renderer::render` draws and the textures to
/// free after the frame.
pub fn prepare(
    ctx: &egui::Context,
    renderer: &mut egui_wgpu::Renderer,
    gpu: &octopaint_gpu::Gpu,
    size: [u32; 2],
    s: &Status,
    palette_at: Option<[f32; 2]>,
    cursor: Option<([f32; 2], f32)>,
) -> (Vec<egui::ClippedPrimitive>, egui_wgpu::ScreenDescriptor, Vec<egui::TextureId>) {
    // About 1/4 of the eye's width for the panel whatever its resolution.
    let ppp = (size[0] as f32 / 900.0).max(0.3);
    let raw = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(size[0] as f32 / ppp, size[1] as f32 / ppp))),
        ..Default::default()
    };
    ctx.set_pixels_per_point(ppp);
    let p = s.painter;
    let out = ctx.run_ui(raw, |ui| {
        if let Some(([x, y], radius)) = cursor {
            // The brush's ghost: a faint ring of its colour and radius, a
            // dot at its centre (docs/vr.md; the desktop's cursor).
            let c = PALETTE[p.colour].map(|v| (v * 255.0) as u8);
            let colour = egui::Color32::from_rgba_unmultiplied(c[0], c[1], c[2], 200);
            let painter = ui.ctx().layer_painter(egui::LayerId::new(egui::Order::Background, egui::Id::unique("cursor")));
            let at = egui::pos2(x / ppp, y / ppp);
            // At least 5 pixels wide, so that a small brush far away
            // still shows; the ring 2 pixels thick at any resolution.
            painter.circle_stroke(at, radius.max(5.0) / ppp, egui::Stroke::new(2.0 / ppp, colour));
            painter.circle_filled(at, 1.5 / ppp, colour);
        }
        if let Some([x, y]) = palette_at {
            // The palette beside the left controller: every colour, the
            // chosen one framed, and the mode and shape.
            egui::Area::new(egui::Id::unique("palette")).fixed_pos(egui::pos2(x / ppp + 8.0, y / ppp - 20.0)).show(ui.ctx(), |ui| {
                egui::Frame::popup(ui.style()).show(ui, |ui| {
                    // The pages, the one shown strong (the left trigger turns them).
                    ui.horizontal(|ui| {
                        for page in PAGES {
                            if page == p.page {
                                ui.strong(page.name());
                            } else {
                                ui.weak(page.name());
                            }
                        }
                    });
                    match p.page {
                        Page::Brush => {
                            ui.horizontal(|ui| {
                                for (k, c) in PALETTE.iter().enumerate() {
                                    let c = c.map(|v| (v * 255.0) as u8);
                                    let (rect, _) = ui.allocate_exact_size(egui::vec2(14.0, 14.0), egui::Sense::hover());
                                    ui.painter().rect_filled(rect, 2.0, egui::Color32::from_rgb(c[0], c[1], c[2]));
                                    if k == p.colour && p.preset_colour.is_none() {
                                        ui.painter().rect_stroke(
                                            rect.expand(2.0),
                                            2.0,
                                            egui::Stroke::new(2.0, egui::Color32::WHITE),
                                            egui::StrokeKind::Outside,
                                        );
                                    }
                                }
                            });
                            if let Some(c) = p.preset_colour {
                                // A preset's colour, framed as the chosen one.
                                let c = c.map(|v| (v * 255.0).round() as u8);
                                ui.horizontal(|ui| {
                                    let (rect, _) = ui.allocate_exact_size(egui::vec2(14.0, 14.0), egui::Sense::hover());
                                    ui.painter().rect_filled(rect, 2.0, egui::Color32::from_rgb(c[0], c[1], c[2]));
                                    ui.painter().rect_stroke(rect.expand(2.0), 2.0, egui::Stroke::new(2.0, egui::Color32::WHITE), egui::StrokeKind::Outside);
                                    ui.weak("the preset's colour");
                                });
                            }
                            ui.label(format!("{} · {}", Mode::ALL[p.mode].name(), Shape::ALL[p.shape].name()));
                        }
                        Page::Presets if p.presets.is_empty() => {
                            ui.label("no presets");
                        }
                        Page::Presets => {
                            // Up to 7 names about the one pointed at.
                            let n = p.presets.len();
                            let first = p.preset.saturating_sub(3).min(n.saturating_sub(7));
                            for (k, preset) in p.presets.iter().enumerate().skip(first).take(7) {
                                if k == p.preset {
                                    ui.label(egui::RichText::new(&preset.name).strong().background_color(egui::Color32::from_rgb(40, 70, 120)));
                                } else {
                                    ui.label(&preset.name);
                                }
                            }
                            ui.weak("stick ↕ choose · X take its brush");
                        }
                        Page::Layers => match &s.layers {
                            // Top first, as the window lists them.
                            Some((rows, selected)) => {
                                for (k, l) in rows.iter().enumerate().rev() {
                                    let mut text = format!("{} {}", if l.visible { "●" } else { "○" }, l.name);
                                    if l.opacity < 1.0 {
                                        text += &format!(" {:.0}%", l.opacity * 100.0);
                                    }
                                    if l.locked {
                                        text += " (locked)";
                                    }
                                    if k == *selected {
                                        ui.label(egui::RichText::new(text).strong().background_color(egui::Color32::from_rgb(40, 70, 120)));
                                    } else {
                                        ui.label(text);
                                    }
                                    ui.weak(egui::RichText::new(octopaint_ui::layer_figures(l.cells, l.bytes, s.capacity)).small());
                                }
                                ui.weak("stick ↕ select · ↔ opacity · X show · Y new");
                            }
                            None => {
                                ui.label("one layer");
                                ui.weak("Y: new layer (makes layers)");
                            }
                        },
                        Page::Mirror => {
                            let a = p.mirror.axes;
                            let on = |b: bool| if b { "on" } else { "off" };
                            ui.label(format!("x {} · y {} · z {}", on(a[0]), on(a[1]), on(a[2])));
                            ui.weak("X: x · Y: y · stick ↑: z · ↓: none");
                        }
                    }
                });
            });
        }
        let panel = egui::Area::new(egui::Id::unique("hud")).fixed_pos(egui::pos2(12.0, 12.0)).show(ui.ctx(), |ui| {
            egui::Frame::popup(ui.style()).show(ui, |ui| {
                ui.horizontal(|ui| {
                    // The colour strokes paint with: a preset's, else the palette's.
                    let c = p.preset_colour.unwrap_or(PALETTE[p.colour]).map(|v| (v * 255.0) as u8);
                    let (rect, _) = ui.allocate_exact_size(egui::vec2(18.0, 18.0), egui::Sense::hover());
                    ui.painter().rect_filled(rect, 3.0, egui::Color32::from_rgb(c[0], c[1], c[2]));
                    let (lit, grid) = p.lit_and_grid();
                    let view = match (lit, grid) {
                        (true, true) => " · lit, grid",
                        (true, false) => " · lit",
                        (false, true) => " · grid",
                        (false, false) => "",
                    };
                    ui.label(format!("{} · {} · {:.1} cm{view}", Mode::ALL[p.mode].name(), Shape::ALL[p.shape].name(), p.room_radius * 100.0));
                });
                if let Some((rows, selected)) = &s.layers {
                    // The status line's layer, as in the window.
                    ui.label(format!("layer {} of {}: {}", selected + 1, rows.len(), rows[*selected].name));
                }
                if p.mirror.axes.iter().any(|&a| a) {
                    let a = p.mirror.axes;
                    let names: Vec<&str> = ["x", "y", "z"].iter().zip(a).filter(|(_, on)| *on).map(|(n, _)| *n).collect();
                    ui.label(format!("mirror {}", names.join(", ")));
                }
                ui.label(format!(
                    "1 m = {} of canvas · paints at depth {} (cells of {})",
                    octopaint_tree::view::length(s.canvas_per_metre),
                    s.depth,
                    octopaint_tree::view::length(s.edge)
                ));
                let pct = 100.0 * f64::from(s.cells) / f64::from(s.capacity.max(1));
                let budget = format!("cells {pct:.1}% of budget · {:.0} MiB", s.bytes as f64 / f64::from(1 << 20));
                if pct > 90.0 {
                    ui.colored_label(egui::Color32::RED, budget);
                } else {
                    ui.label(budget);
                }
                match &s.busy {
                    Some(b) => octopaint_ui::indicator(ui, &b.text, b.progress, 160.0),
                    None if s.in_stroke => {
                        ui.colored_label(egui::Color32::YELLOW, "painting…");
                    }
                    None => {}
                }
                if let Some(e) = &p.last_error {
                    ui.colored_label(egui::Color32::RED, e);
                }
            });
        });
        // The canvas axes under the panel (head-locked, like the desktop
        // window's gizmo): x red, y green, z blue, the far ones thinner and
        // drawn first.
        let origin = panel.response.rect.left_bottom() + egui::vec2(34.0, 38.0);
        let painter = ui.ctx().layer_painter(egui::LayerId::new(egui::Order::Foreground, egui::Id::unique("axes")));
        octopaint_ui::axes_gizmo(&painter, origin, 24.0, &s.axes, false);
    });
    for (id, deltas) in &out.textures_delta.set {
        for d in deltas {
            renderer.update_texture(&gpu.device, &gpu.queue, *id, d);
        }
    }
    let jobs = ctx.tessellate(out.shapes, out.pixels_per_point);
    (jobs, egui_wgpu::ScreenDescriptor { size_in_pixels: size, pixels_per_point: out.pixels_per_point }, out.textures_delta.free.iter().copied().collect())
}
