//! The panel (docs/desktop.md): the brush, the lighting, the layers, the
//! buttons and the status line, drawn with egui each frame from what the
//! engine published; every change the artist makes is an [`Action`] the
//! app turns into a job.

use octopaint_tree::layers::MAX_LAYERS;
use octopaint_tree::trace::{LayerOp, LayerOpKind, MODES, Mode, SHAPES, Shape};
use octopaint_tree::view::length;

use crate::brush::BrushUi;
use crate::overlay::Overlay;

/// The layer panel's state (docs/desktop.md "Layers").
#[derive(Default)]
pub(crate) struct LayersUi {
    pub(crate) rename: String,
    /// The selected layer's opacity while its slider is dragged (applied,
    /// as one undo step, when the drag ends).
    pub(crate) opacity: Option<f32>,
    /// Where the last frame laid out each layer's row and drag handle
    /// (by layer index): a test drives the panel with pointer events there.
    pub(crate) rows: Vec<(usize, egui::Rect, egui::Rect)>,
}

/// One row of the layer panel.
pub(crate) struct LayerInfo {
    pub(crate) name: String,
    pub(crate) visible: bool,
    pub(crate) opacity: f32,
    pub(crate) locked: bool,
    /// Cells in use and the bytes of its pools (shown under its row).
    pub(crate) cells: u32,
    pub(crate) bytes: usize,
}

pub(crate) struct StatusInfo {
    pub(crate) fps: f64,
    /// The share of the window's width the rays were cast for.
    pub(crate) resolution: f64,
    pub(crate) latency_ms: Option<f64>,
    /// What the stroke thread is busy with, when it has been for a while
    /// or work is queued (the heavy-operation indicator), with the share
    /// of the queued work done.
    pub(crate) busy: Option<(String, Option<f32>)>,
    pub(crate) cells: u32,
    pub(crate) capacity: u32,
    pub(crate) bytes: usize,
    pub(crate) undo: usize,
    pub(crate) redo: usize,
    pub(crate) message: String,
    /// A document of layers (a version 2 session); else one tree.
    pub(crate) layered: bool,
    pub(crate) layers: Vec<LayerInfo>,
    pub(crate) selected: usize,
    /// The brush presets' names, in their file's order.
    pub(crate) presets: Vec<String>,
}

pub(crate) enum Action {
    Undo,
    Redo,
    Save,
    Screenshot,
    Frame,
    MirrorHere,
    /// Make this one-tree document a document of layers.
    MakeLayers,
    Layer(LayerOp),
    /// Brush presets (docs/desktop.md "Brush presets"): take the named
    /// one's brush; keep the current brush under a name; delete one.
    ApplyPreset(String),
    SavePreset(String),
    DeletePreset(String),
}

/// The smallest `Layer N` not taken.
pub(crate) fn free_name(layers: &[LayerInfo], stem: &str) -> String {
    (1..).map(|n| format!("{stem} {n}")).find(|n| !layers.iter().any(|l| l.name == *n)).expect("some name is free")
}

pub(crate) fn layer_op(kind: LayerOpKind, layer: Option<&str>, name: Option<String>) -> LayerOp {
    LayerOp { layer: layer.map(String::from), name, ..LayerOp::new(kind) }
}

/// The brush presets (docs/desktop.md "Brush presets"): a list to choose
/// one from (its whole brush is taken), a name field (the chosen name, or
/// a new one) with Save (the current brush under that name, replacing a
/// preset of that name) and Delete.
pub(crate) fn presets_row(ui: &mut egui::Ui, b: &mut BrushUi, s: &StatusInfo, actions: &mut Vec<Action>) {
    let shown = if s.presets.contains(&b.preset) { b.preset.as_str() } else { "choose…" };
    egui::ComboBox::from_label("preset").selected_text(shown).show_ui(ui, |ui| {
        for name in &s.presets {
            if ui.selectable_label(*name == b.preset, name).clicked() {
                actions.push(Action::ApplyPreset(name.clone()));
            }
        }
    });
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut b.preset).hint_text("preset name").desired_width(110.0));
        let name = b.preset.trim().to_string();
        if ui.add_enabled(!name.is_empty(), egui::Button::new("Save")).on_hover_text("keep the current brush under this name").clicked() {
            actions.push(Action::SavePreset(name.clone()));
        }
        if ui.add_enabled(s.presets.contains(&name), egui::Button::new("Delete")).on_hover_text("delete the preset of this name").clicked() {
            actions.push(Action::DeletePreset(name));
        }
    });
}

/// The layer panel (docs/desktop.md "Layers"): the layers top first, each
/// selectable, with its eye and its lock; the selected one's opacity and
/// name; add, duplicate, delete, merge down, move up and down. Every change
/// is a `layer` event of the document, an undo step.
pub(crate) fn layers_panel(ui: &mut egui::Ui, l: &mut LayersUi, s: &StatusInfo, actions: &mut Vec<Action>) {
    ui.heading("Layers");
    if !s.layered {
        ui.label("one tree");
        if ui.button("Use layers").on_hover_text("make this document a document of layers (it is saved at once)").clicked() {
            actions.push(Action::MakeLayers);
        }
        return;
    }
    let n = s.layers.len();
    l.rows.clear();
    for k in (0..n).rev() {
        let layer = &s.layers[k];
        let row = ui.horizontal(|ui| {
            // The handle: drag a layer onto another row to move it there
            // (a `move` event to that row's index).
            let handle = ui.dnd_drag_source(egui::Id::unique(("layer row", k)), k, grip).response.on_hover_text("drag onto another layer to move it there");
            let mut visible = layer.visible;
            if ui.checkbox(&mut visible, "").on_hover_text("visible (drawn, exported)").changed() {
                actions.push(Action::Layer(LayerOp { visible: Some(visible), ..layer_op(LayerOpKind::Set, Some(&layer.name), None) }));
            }
            let mut locked = layer.locked;
            if ui.checkbox(&mut locked, "lock").on_hover_text("locked: strokes are refused").changed() {
                actions.push(Action::Layer(LayerOp { locked: Some(locked), ..layer_op(LayerOpKind::Set, Some(&layer.name), None) }));
            }
            let label = if layer.opacity < 1.0 { format!("{} ({:.0}%)", layer.name, layer.opacity * 100.0) } else { layer.name.clone() };
            if ui.selectable_label(k == s.selected, label).clicked() && k != s.selected {
                actions.push(Action::Layer(layer_op(LayerOpKind::Select, Some(&layer.name), None)));
                l.rename.clear();
                l.opacity = None;
            }
            handle.rect
        });
        ui.weak(egui::RichText::new(octopaint_ui::layer_figures(layer.cells, layer.bytes, s.capacity)).small());
        let rect = row.response.rect;
        l.rows.push((k, rect, row.inner));
        if let Some(from) = row.response.dnd_hover_payload::<usize>()
            && *from != k
        {
            // Where it would go: a line on the side it comes from.
            let y = if *from < k { rect.top() } else { rect.bottom() };
            ui.painter().hline(rect.x_range(), y, egui::Stroke::new(2.0, ui.visuals().selection.stroke.color));
        }
        if let Some(from) = row.response.dnd_release_payload::<usize>()
            && *from != k
            && let Some(moved) = s.layers.get(*from)
        {
            actions.push(Action::Layer(LayerOp { to: Some(k), ..layer_op(LayerOpKind::Move, Some(&moved.name), None) }));
        }
    }
    let Some(current) = s.layers.get(s.selected) else { return };
    let name = current.name.as_str();
    let mut opacity = l.opacity.unwrap_or(current.opacity);
    let slider = ui.add(egui::Slider::new(&mut opacity, 0.0..=1.0).text("layer opacity"));
    if slider.dragged() {
        l.opacity = Some(opacity);
    } else if slider.drag_stopped() || (slider.changed() && !slider.dragged()) {
        l.opacity = None;
        if opacity != current.opacity {
            actions.push(Action::Layer(LayerOp { opacity: Some(opacity), ..layer_op(LayerOpKind::Set, Some(name), None) }));
        }
    }
    ui.horizontal(|ui| {
        ui.add(egui::TextEdit::singleline(&mut l.rename).hint_text(name).desired_width(110.0));
        if ui.button("Rename").clicked() && !l.rename.trim().is_empty() {
            actions.push(Action::Layer(layer_op(LayerOpKind::Rename, Some(name), Some(l.rename.trim().to_string()))));
            l.rename.clear();
        }
    });
    ui.horizontal(|ui| {
        if ui.add_enabled(n < MAX_LAYERS, egui::Button::new("Add")).clicked() {
            actions.push(Action::Layer(layer_op(LayerOpKind::Add, None, Some(free_name(&s.layers, "Layer")))));
        }
        if ui.add_enabled(n < MAX_LAYERS, egui::Button::new("Duplicate")).clicked() {
            actions.push(Action::Layer(layer_op(LayerOpKind::Duplicate, Some(name), Some(free_name(&s.layers, &format!("{name} copy"))))));
        }
        if ui.add_enabled(n > 1, egui::Button::new("Delete")).clicked() {
            actions.push(Action::Layer(layer_op(LayerOpKind::Delete, Some(name), None)));
        }
    });
    ui.horizontal(|ui| {
        let below_locked = s.selected > 0 && s.layers[s.selected - 1].locked;
        if ui.add_enabled(s.selected > 0 && !current.locked && !below_locked, egui::Button::new("Merge down")).clicked() {
            actions.push(Action::Layer(layer_op(LayerOpKind::MergeDown, Some(name), None)));
        }
        if ui.add_enabled(s.selected + 1 < n, egui::Button::new("Up")).clicked() {
            actions.push(Action::Layer(LayerOp { to: Some(s.selected + 1), ..layer_op(LayerOpKind::Move, Some(name), None) }));
        }
        if ui.add_enabled(s.selected > 0, egui::Button::new("Down")).clicked() {
            actions.push(Action::Layer(LayerOp { to: Some(s.selected - 1), ..layer_op(LayerOpKind::Move, Some(name), None) }));
        }
    });
}

/// The panel, the status line and the overlay; returns the part of the
/// window they leave for the view (points).
pub(crate) fn panel(root: &mut egui::Ui, b: &mut BrushUi, l: &mut LayersUi, s: &StatusInfo, overlay: &Overlay, actions: &mut Vec<Action>) -> egui::Rect {
    status_line(root, s);
    egui::Panel::left("brush").resizable(false).show(root, |ui| egui::ScrollArea::vertical().show(ui, |ui| {
        ui.heading("Brush");
        presets_row(ui, b, s, actions);
        egui::ComboBox::from_label("shape").selected_text(b.shape.name()).show_ui(ui, |ui| {
            for (v, name) in Shape::ALL.into_iter().zip(SHAPES) {
                ui.selectable_value(&mut b.shape, v, name);
            }
        });
        egui::ComboBox::from_label("mode").selected_text(b.mode.name()).show_ui(ui, |ui| {
            for (v, name) in Mode::ALL.into_iter().zip(MODES) {
                ui.selectable_value(&mut b.mode, v, name);
            }
        });
        ui.add(egui::Slider::new(&mut b.radius, 1e-4..=1e4).logarithmic(true).text("radius"));
        ui.add(egui::Slider::new(&mut b.opacity, 0.0..=1.0).text("opacity"));
        ui.add(egui::Slider::new(&mut b.hardness, 0.0..=1.0).text("hardness"));
        ui.horizontal(|ui| {
            ui.label("colour");
            ui.color_edit_button_rgb(&mut b.colour);
        });
        ui.checkbox(&mut b.on_surface, "paint on the surface under the cursor");
        ui.add(egui::Slider::new(&mut b.plane_depth, 1e-4..=1e5).logarithmic(true).text("plane depth"));
        ui.horizontal(|ui| {
            ui.label("mirror");
            for (a, name) in ["x (M)", "y", "z"].into_iter().enumerate() {
                ui.checkbox(&mut b.mirror_axes[a], name);
            }
        });
        ui.horizontal(|ui| {
            let c = b.mirror_centre;
            ui.label(format!("centre {}, {}, {}", length(c.x), length(c.y), length(c.z)));
            if ui.button("here").on_hover_text("move the mirror planes to the view's centre").clicked() {
                actions.push(Action::MirrorHere);
            }
        });
        ui.checkbox(&mut b.grid, "ground grid and horizon (G)");
        ui.add(egui::Slider::new(&mut b.lod, 0.0..=4.0).step_by(0.25).text("level of detail")).on_hover_text(
            "rays stop at cells no wider than this many pixels and draw their children's average: \
             1 is about a cell per pixel; 0 walks every ray to the smallest cells (slower, shimmers when moving)",
        );
        ui.horizontal(|ui| {
            ui.checkbox(&mut b.light.on, "light (L)");
            ui.add_enabled(b.light.on, egui::Checkbox::new(&mut b.light.shadows, "shadows (Shift+L)"));
        });
        ui.add_enabled_ui(b.light.on, |ui| {
            ui.checkbox(&mut b.light.follows_view, "light turns with the view");
            ui.add(egui::Slider::new(&mut b.light.azimuth, -180.0..=180.0).text("light azimuth °"));
            ui.add(egui::Slider::new(&mut b.light.elevation, -90.0..=90.0).text("light elevation °"));
            ui.add(egui::Slider::new(&mut b.light.intensity, 0.0..=2.0).text("intensity"));
            ui.add(egui::Slider::new(&mut b.light.ambient, 0.0..=1.0).text("ambient"));
        });
        let (per_px, radius, depth, edge) = overlay.scale;
        ui.label(format!("1 px = {} at the brush\nradius {} paints at depth {depth}\n(cells of {})", length(per_px), length(radius), length(edge)));
        ui.separator();
        ui.horizontal(|ui| {
            if ui.button("Undo").clicked() {
                actions.push(Action::Undo);
            }
            if ui.button("Redo").clicked() {
                actions.push(Action::Redo);
            }
            if ui.button("Save").clicked() {
                actions.push(Action::Save);
            }
            if ui.button("Screenshot").clicked() {
                actions.push(Action::Screenshot);
            }
            if ui.button("Frame").on_hover_text("frame the painting (F)").clicked() {
                actions.push(Action::Frame);
            }
        });
        ui.separator();
        layers_panel(ui, l, s, actions);
        ui.separator();
        ui.label("left drag: paint · right drag: orbit\nwheel: zoom · W A S D Q E: fly\nF: frame the painting · G: grid\nL: light · Shift+L: shadows\nM: mirror on x\n[ ]: brush size\nCtrl+Z / Ctrl+Y: undo / redo\nCtrl+S: save · F12: screenshot");
    }));
    let view = root.available_rect_before_wrap();
    overlay.draw(root.ctx(), view);
    view
}

pub(crate) fn status_line(root: &mut egui::Ui, s: &StatusInfo) {
    egui::Panel::bottom("status").show(root, |ui| {
        ui.horizontal(|ui| {
            ui.label(format!("{:.0} fps", s.fps));
            ui.separator();
            ui.label(format!("resolution {:.0}%", s.resolution * 100.0));
            ui.separator();
            ui.label(match s.latency_ms {
                Some(l) => format!("latency {l:.1} ms"),
                None => "latency -".into(),
            });
            ui.separator();
            let pct = 100.0 * f64::from(s.cells) / f64::from(s.capacity.max(1));
            ui.label(format!("{} cells, budget {pct:.1}% of {}", s.cells, s.capacity));
            ui.separator();
            ui.label(format!("memory {:.1} MiB", s.bytes as f64 / f64::from(1 << 20)));
            ui.separator();
            ui.label(format!("undo {} / redo {}", s.undo, s.redo));
            if s.layered
                && let Some(l) = s.layers.get(s.selected)
            {
                ui.separator();
                ui.label(format!("layer {}{}", l.name, if l.locked { " (locked)" } else { "" }));
            }
            if let Some((what, done)) = &s.busy {
                // The heavy-operation indicator (the paper's 8.3): painting
                // goes on on its own thread while frames keep coming.
                ui.separator();
                octopaint_ui::indicator(ui, what, *done, 90.0);
            }
            if pct > 90.0 {
                ui.separator();
                ui.colored_label(egui::Color32::RED, "cell budget nearly spent");
            }
            if !s.message.is_empty() {
                ui.separator();
                ui.label(&s.message);
            }
        });
    });
}

/// A layer row's drag handle: three short lines drawn with the painter
/// (a glyph such as an arrow is missing from the fonts egui ships).
fn grip(ui: &mut egui::Ui) {
    let (rect, _) = ui.allocate_exact_size(egui::vec2(12.0, 14.0), egui::Sense::hover());
    let colour = ui.visuals().widgets.inactive.fg_stroke.color;
    for k in 0..3 {
        let y = rect.top() + 3.5 + 3.5 * k as f32;
        ui.painter().hline(rect.left() + 1.0..=rect.right() - 1.0, y, egui::Stroke::new(1.5, colour));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn info(names: &[&str]) -> StatusInfo {
        StatusInfo {
            fps: 0.0,
            resolution: 1.0,
            latency_ms: None,
            busy: None,
            cells: 8,
            capacity: 1 << 20,
            bytes: 0,
            undo: 0,
            redo: 0,
            message: String::new(),
            layered: true,
            layers: names
                .iter()
                .enumerate()
                .map(|(k, n)| LayerInfo { name: n.to_string(), visible: true, opacity: 1.0, locked: false, cells: 8 + 8 * k as u32, bytes: 4096 })
                .collect(),
            selected: 0,
            presets: vec!["fine liner".into(), "haze".into()],
        }
    }

    /// One frame of the panel with these pointer events; the actions it made.
    fn frame(ctx: &egui::Context, l: &mut LayersUi, s: &StatusInfo, events: Vec<egui::Event>) -> Vec<Action> {
        let raw = egui::RawInput { screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(400.0, 600.0))), events, ..Default::default() };
        let mut actions = Vec::new();
        let _ = ctx.run_ui(raw, |ui| {
            egui::CentralPanel::default().show(ui, |ui| layers_panel(ui, l, s, &mut actions));
        });
        actions
    }

    fn pointer(at: egui::Pos2, pressed: Option<bool>) -> Vec<egui::Event> {
        let mut e = vec![egui::Event::PointerMoved(at)];
        if let Some(p) = pressed {
            e.push(egui::Event::PointerButton { pos: at, button: egui::PointerButton::Primary, pressed: p, modifiers: Default::default() });
        }
        e
    }

    #[test]
    fn every_layer_row_shows_its_figures() {
        let ctx = egui::Context::default();
        let s = info(&["bottom", "top"]);
        let raw = egui::RawInput { screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(400.0, 600.0))), ..Default::default() };
        let out = ctx.run_ui(raw, |ui| {
            egui::CentralPanel::default().show(ui, |ui| layers_panel(ui, &mut LayersUi::default(), &s, &mut Vec::new()));
        });
        let texts: Vec<String> = out
            .shapes
            .iter()
            .filter_map(|c| match &c.shape {
                egui::Shape::Text(t) => Some(t.galley.text().to_string()),
                _ => None,
            })
            .collect();
        for layer in &s.layers {
            let want = octopaint_ui::layer_figures(layer.cells, layer.bytes, s.capacity);
            assert!(texts.contains(&want), "{want:?} not among {texts:?}");
        }
    }

    #[test]
    fn dragging_a_layer_onto_another_row_moves_it_there() {
        let ctx = egui::Context::default();
        let s = info(&["bottom", "middle", "top"]);
        let mut l = LayersUi::default();
        assert!(frame(&ctx, &mut l, &s, vec![]).is_empty());
        let find = |l: &LayersUi, k: usize| *l.rows.iter().find(|r| r.0 == k).expect("a row per layer");
        let (_, _, handle) = find(&l, 0);
        let (_, target, _) = find(&l, 2);
        // Press on the bottom layer's handle, drag in steps to the top row,
        // release there.
        let mut actions = frame(&ctx, &mut l, &s, pointer(handle.center(), Some(true)));
        let (from, to) = (handle.center(), target.center());
        for i in 1..=8 {
            let t = i as f32 / 8.0;
            actions.extend(frame(&ctx, &mut l, &s, pointer(from + (to - from) * t, None)));
        }
        actions.extend(frame(&ctx, &mut l, &s, pointer(to, Some(false))));
        actions.extend(frame(&ctx, &mut l, &s, vec![]));
        let moves: Vec<&LayerOp> =
            actions.iter().filter_map(|a| if let Action::Layer(op) = a { Some(op) } else { None }).filter(|op| op.op == LayerOpKind::Move).collect();
        assert_eq!(moves.len(), 1, "one move");
        assert_eq!((moves[0].layer.as_deref(), moves[0].to), (Some("bottom"), Some(2)));
        // A click on a handle without moving is no move.
        let (_, _, handle) = find(&l, 1);
        let mut actions = frame(&ctx, &mut l, &s, pointer(handle.center(), Some(true)));
        actions.extend(frame(&ctx, &mut l, &s, pointer(handle.center(), Some(false))));
        assert!(!actions.iter().any(|a| matches!(a, Action::Layer(op) if op.op == LayerOpKind::Move)));
    }
}

#[cfg(test)]
mod preset_tests {
    use super::*;
    use crate::brush::LightUi;
    use glam::DVec3;
    use octopaint_tree::trace::Brush;

    fn brush_ui() -> BrushUi {
        BrushUi {
            shape: Shape::Sphere,
            mode: Mode::Paint,
            radius: 0.1,
            opacity: 0.8,
            hardness: 0.6,
            colour: [0.9, 0.45, 0.15],
            on_surface: true,
            plane_depth: 1.0,
            grid: true,
            light: LightUi::default(),
            mirror_axes: [false; 3],
            mirror_centre: DVec3::ZERO,
            lod: 0.0,
            rest: Brush::new(Shape::Sphere, Mode::Paint, 1.0, [0.0; 3], 1.0, 0.5),
            preset: String::new(),
        }
    }

    #[test]
    fn a_preset_gives_the_panel_its_whole_brush() {
        let mut b = brush_ui();
        for p in octopaint_doc::presets::starting_set() {
            b.apply(&p.brush);
            let got = b.brush();
            // The panel keeps the colour as f32: the preset's, rounded once.
            assert_eq!(Brush { color: p.brush.color.map(|c| f64::from(c as f32)), ..p.brush }, got, "{}", p.name);
        }
    }

    /// The centre of the first text `want` the frame drew.
    fn text_at(shapes: &[egui::epaint::ClippedShape], want: &str) -> Option<egui::Pos2> {
        shapes.iter().find_map(|c| match &c.shape {
            egui::Shape::Text(t) if t.galley.text() == want => Some(t.pos + t.galley.rect.center().to_vec2()),
            _ => None,
        })
    }

    #[test]
    fn save_and_delete_name_the_field_s_preset() {
        let ctx = egui::Context::default();
        let s = super::tests::info(&[]);
        let mut b = brush_ui();
        b.preset = "haze".into();
        let run = |b: &mut BrushUi, events: Vec<egui::Event>| {
            let raw = egui::RawInput { screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(400.0, 300.0))), events, ..Default::default() };
            let mut actions = Vec::new();
            let out = ctx.run_ui(raw, |ui| {
                egui::CentralPanel::default().show(ui, |ui| presets_row(ui, b, &s, &mut actions));
            });
            (out.shapes, actions)
        };
        let (shapes, _) = run(&mut b, vec![]);
        assert!(text_at(&shapes, "haze").is_some(), "the chosen preset is shown");
        for (button, want) in [("Save", "save"), ("Delete", "delete")] {
            let at = text_at(&shapes, button).expect("the button");
            let click = |pressed| egui::Event::PointerButton { pos: at, button: egui::PointerButton::Primary, pressed, modifiers: Default::default() };
            let (_, mut actions) = run(&mut b, vec![egui::Event::PointerMoved(at), click(true)]);
            actions.extend(run(&mut b, vec![click(false)]).1);
            let got: Vec<String> = actions
                .iter()
                .filter_map(|a| match a {
                    Action::SavePreset(n) => Some(format!("save {n}")),
                    Action::DeletePreset(n) => Some(format!("delete {n}")),
                    _ => None,
                })
                .collect();
            assert_eq!(got, vec![format!("{want} haze")]);
        }
        // A name no preset has: Save, but no Delete.
        b.preset = "new one".into();
        let (shapes, _) = run(&mut b, vec![]);
        assert!(text_at(&shapes, "choose…").is_some());
    }
}
