//! The egui drawings the desktop window and the headset share (docs/desktop.md
//! "Aids", docs/vr.md): the canvas axes gizmo, the heavy-operation
//! indicator and a layer's figures. Each front end places them (the window in a corner of its
//! view, the headset on its head-locked panel) and chooses their size.

/// The axes' colours: x red, y green, z blue.
pub const AXIS_COLOURS: [egui::Color32; 3] =
    [egui::Color32::from_rgb(230, 60, 60), egui::Color32::from_rgb(70, 200, 70), egui::Color32::from_rgb(70, 120, 240)];

/// The canvas axes x, y, z as the viewer sees them (`axes`: each one's
/// direction on the screen, y down, and whether it points away; see
/// `octopaint_tree::view::axes_seen_from`), drawn from `origin` on a dark
/// disc, `length` points long, the far ones thinner and drawn first so
/// the near ones cover them; `labels`: name each axis at its tip.
pub fn axes_gizmo(painter: &egui::Painter, origin: egui::Pos2, length: f32, axes: &[([f32; 2], bool); 3], labels: bool) {
    painter.circle_filled(origin, length * 1.22, egui::Color32::from_rgba_unmultiplied(0, 0, 0, 110));
    let mut order = [0usize, 1, 2];
    order.sort_by_key(|&i| !axes[i].1);
    // Widths in proportion: 2 and 3.5 points at the window's 36.
    let (far, near) = (length / 18.0, length / 10.3);
    for i in order {
        let (v, away) = axes[i];
        let dir = egui::vec2(v[0], v[1]);
        let tip = origin + dir * length;
        painter.line_segment([origin, tip], egui::Stroke::new(if away { far } else { near }, AXIS_COLOURS[i]));
        if labels {
            painter.text(tip + dir * 8.0, egui::Align2::CENTER_CENTER, ["x", "y", "z"][i], egui::FontId::proportional(12.0), AXIS_COLOURS[i]);
        }
    }
}

/// The heavy-operation indicator (the paper's 8.3): a spinner, what runs
/// (`text`) and, while jobs are queued, a bar of the share done.
pub fn indicator(ui: &mut egui::Ui, text: &str, progress: Option<f32>, bar_width: f32) {
    ui.horizontal(|ui| {
        ui.add(egui::Spinner::new());
        ui.colored_label(egui::Color32::YELLOW, text);
        if let Some(done) = progress {
            ui.add(egui::ProgressBar::new(done.clamp(0.0, 1.0)).desired_width(bar_width).show_percentage());
        }
    });
}

/// A layer's figures for the layer panels (docs/desktop.md "Layers"): its
/// cells in use, the MiB its pools hold, and its share of the document's
/// cell budget (`capacity`, shared by every layer), e.g. `1.25 M cells ·
/// 19.6 MiB · 7.5 % of the budget`.
pub fn layer_figures(cells: u32, bytes: usize, capacity: u32) -> String {
    let count = match cells {
        0..10_000 => format!("{cells}"),
        10_000..1_000_000 => format!("{:.1} k", f64::from(cells) / 1e3),
        _ => format!("{:.2} M", f64::from(cells) / 1e6),
    };
    let share = if capacity > 0 { 100.0 * f64::from(cells) / f64::from(capacity) } else { 0.0 };
    let share = if share > 0.0 && share < 0.1 { "< 0.1".to_string() } else { format!("{share:.1}") };
    format!("{count} cells · {:.1} MiB · {share} % of the budget", bytes as f64 / (1u64 << 20) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layer_figures_name_cells_mib_and_the_share_of_the_budget() {
        assert_eq!(layer_figures(8, 1 << 20, 1 << 20), "8 cells · 1.0 MiB · < 0.1 % of the budget");
        assert_eq!(layer_figures(0, 0, 1 << 20), "0 cells · 0.0 MiB · 0.0 % of the budget");
        assert_eq!(layer_figures(12_345, 3 << 19, 1_000_000), "12.3 k cells · 1.5 MiB · 1.2 % of the budget");
        assert_eq!(layer_figures(1_250_000, 20_552_089, 16_666_667), "1.25 M cells · 19.6 MiB · 7.5 % of the budget");
        assert_eq!(layer_figures(u32::MAX - 7, 0, u32::MAX - 7), "4294.97 M cells · 0.0 MiB · 100.0 % of the budget");
    }

    /// The shapes a frame of `draw` gives, tessellated.
    fn shapes(draw: impl FnMut(&mut egui::Ui)) -> Vec<egui::epaint::ClippedShape> {
        let ctx = egui::Context::default();
        let raw = egui::RawInput { screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(400.0, 300.0))), ..Default::default() };
        let mut draw = draw;
        ctx.run_ui(raw, |ui| draw(ui)).shapes
    }

    fn segments(shapes: &[egui::epaint::ClippedShape]) -> Vec<(egui::Pos2, egui::Pos2, f32, egui::Color32)> {
        shapes
            .iter()
            .filter_map(|s| match &s.shape {
                egui::Shape::LineSegment { points, stroke } => Some((points[0], points[1], stroke.width, stroke.color)),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn the_gizmo_draws_the_far_axes_first_and_thinner() {
        // x to the right (near), y up (away), z towards the viewer's lower left (near).
        let axes = [([1.0, 0.0], false), ([0.0, -1.0], true), ([-0.6, 0.8], false)];
        let origin = egui::pos2(100.0, 100.0);
        let all = shapes(|ui| axes_gizmo(ui.painter(), origin, 36.0, &axes, true));
        let lines = segments(&all);
        assert_eq!(lines.len(), 3);
        // y (away) first, thinner; then x and z.
        assert_eq!(lines[0].3, AXIS_COLOURS[1]);
        assert!(lines[0].2 < lines[1].2 && lines[0].2 < lines[2].2);
        for (a, b, _, colour) in &lines {
            assert_eq!(*a, origin);
            let i = AXIS_COLOURS.iter().position(|c| c == colour).unwrap();
            let want = origin + egui::vec2(axes[i].0[0], axes[i].0[1]) * 36.0;
            assert!((*b - want).length() < 1e-4, "axis {i} ends at {b:?}, not {want:?}");
        }
        let texts = all.iter().filter(|s| matches!(s.shape, egui::Shape::Text(_))).count();
        assert_eq!(texts, 3);
        let unlabelled = shapes(|ui| axes_gizmo(ui.painter(), origin, 24.0, &axes, false));
        assert_eq!(unlabelled.iter().filter(|s| matches!(s.shape, egui::Shape::Text(_))).count(), 0);
    }
}
