//! The brush and the view's light as the panel edits them.

use glam::{DQuat, DVec3};
use octopaint_tree::trace::{Brush, Light, Mirror, Mode, Shape};

/// The brush as the panel edits it.
pub(crate) struct BrushUi {
    pub(crate) shape: Shape,
    pub(crate) mode: Mode,
    /// Radius in canvas units.
    pub(crate) radius: f64,
    pub(crate) opacity: f64,
    pub(crate) hardness: f64,
    pub(crate) colour: [f32; 3],
    pub(crate) on_surface: bool,
    /// Distance of the painting plane from the eye along the view axis,
    /// canvas units (strokes off the surface, or with surface painting
    /// off, lie on that plane).
    pub(crate) plane_depth: f64,
    /// The ground grid and horizon behind the painting (G).
    pub(crate) grid: bool,
    /// The view's lighting (L, Shift+L).
    pub(crate) light: LightUi,
    /// Mirror painting (spec 8.11; M toggles x): the axes whose planes
    /// through `mirror_centre` mirror every stroke.
    pub(crate) mirror_axes: [bool; 3],
    pub(crate) mirror_centre: DVec3,
    /// The level of detail of the view (docs/spec.md 7): rays stop at
    /// cells no wider than this many pixels' footprints; 0: at the leaves.
    pub(crate) lod: f64,
    /// The brush fields the panel has no control for (spacing, mix ratio,
    /// pickup rate, aspect, noise), as the last preset chosen set them.
    pub(crate) rest: Brush,
    /// The preset name field (docs/desktop.md "Brush presets").
    pub(crate) preset: String,
}

impl BrushUi {
    /// The mirror planes strokes paint with now; None: no copies.
    pub(crate) fn mirror(&self) -> Option<Mirror> {
        Mirror { axes: self.mirror_axes, centre: self.mirror_centre.to_array() }.active()
    }
}

/// The lighting of the view as the panel edits it (docs/spec.md 6.1,
/// docs/desktop.md "Lighting"): a directional light given by azimuth and
/// elevation, in the view's frame (it turns with the camera, as a studio
/// light in a sculpting tool) or in the canvas's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LightUi {
    pub(crate) on: bool,
    pub(crate) shadows: bool,
    pub(crate) follows_view: bool,
    /// Degrees: azimuth from the view axis (or canvas +z) towards the
    /// right (+x), elevation above the horizontal.
    pub(crate) azimuth: f64,
    pub(crate) elevation: f64,
    pub(crate) intensity: f64,
    pub(crate) ambient: f64,
}

impl Default for LightUi {
    fn default() -> Self {
        LightUi { on: true, shadows: false, follows_view: true, azimuth: 27.0, elevation: 30.0, intensity: 0.8, ambient: 0.3 }
    }
}

impl LightUi {
    /// The light for a view turned by `view` (camera to canvas), or None
    /// when lighting is off.
    pub(crate) fn light(&self, view: DQuat) -> Option<Light> {
        if !self.on {
            return None;
        }
        let (az, el) = (self.azimuth.to_radians(), self.elevation.to_radians());
        let local = DVec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
        let dir = if self.follows_view { view * local } else { local };
        Some(Light { on: true, dir: dir.to_array(), intensity: self.intensity, ambient: self.ambient, shadows: self.shadows })
    }
}

impl BrushUi {
    pub(crate) fn brush(&self) -> Brush {
        Brush {
            shape: self.shape,
            mode: self.mode,
            radius: self.radius,
            color: self.colour.map(f64::from),
            opacity: self.opacity,
            hardness: self.hardness,
            ..self.rest
        }
    }

    /// Take every field of `b` (a preset's brush).
    pub(crate) fn apply(&mut self, b: &Brush) {
        (self.shape, self.mode, self.radius, self.opacity, self.hardness) = (b.shape, b.mode, b.radius, b.opacity, b.hardness);
        self.colour = b.color.map(|c| c as f32);
        self.rest = *b;
    }
}
