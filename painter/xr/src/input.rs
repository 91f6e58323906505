//! Controllers (docs/vr.md, "Controllers"): one action set with suggested
//! bindings for the Khronos simple controller, Valve Index, Oculus Touch
//! and HTC Vive, read into a per-hand state every frame; and scripted
//! controller states that replace them (a test on a simulated headset has
//! no hands to move).

use std::collections::BTreeMap;
use std::path::Path;

use glam::{DQuat, DVec3};
use openxr as xr;

use crate::XrError;

/// One hand, as the painter uses it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Hand {
    /// Aim pose in the session's space: position (metres), orientation.
    pub pose: Option<(DVec3, DQuat)>,
    /// Trigger, 0 to 1 (paints, pressure = value).
    pub trigger: f32,
    /// Grip, 0 to 1 (grabs the canvas past 0.5).
    pub grip: f32,
    /// Thumbstick or trackpad, -1 to 1 each.
    pub stick: [f32; 2],
    /// Primary button (A, X; Vive menu): undo on the painting hand.
    pub primary: bool,
    /// Secondary button (B, Y): redo on the painting hand.
    pub secondary: bool,
}

pub const LEFT: usize = 0;
pub const RIGHT: usize = 1;

pub struct Controls {
    set: xr::ActionSet,
    trigger: xr::Action<f32>,
    grip: xr::Action<f32>,
    stick: xr::Action<xr::Vector2f>,
    primary: xr::Action<bool>,
    secondary: xr::Action<bool>,
    aim: xr::Action<xr::Posef>,
    hands: [xr::Path; 2],
    spaces: Vec<xr::Space>,
}

fn call<T>(what: &'static str, r: Result<T, xr::sys::Result>) -> Result<T, XrError> {
    crate::call(what, r)
}

impl Controls {
    /// The actions, their bindings for four controller families, attached
    /// to `session`.
    pub fn new<G: xr::Graphics>(instance: &xr::Instance, session: &xr::Session<G>) -> Result<Controls, XrError> {
        let left = call("path", instance.string_to_path("/user/hand/left"))?;
        let right = call("path", instance.string_to_path("/user/hand/right"))?;
        let hands = [left, right];
        let set = call("action set", instance.create_action_set("painting", "Painting", 0))?;
        let trigger = call("action", set.create_action::<f32>("paint", "Paint (trigger)", &hands))?;
        let grip = call("action", set.create_action::<f32>("grab", "Grab the canvas (grip)", &hands))?;
        let stick = call("action", set.create_action::<xr::Vector2f>("adjust", "Brush size and palette (thumbstick)", &hands))?;
        let primary = call("action", set.create_action::<bool>("undo", "Undo (primary button)", &hands))?;
        let secondary = call("action", set.create_action::<bool>("redo", "Redo (secondary button)", &hands))?;
        let aim = call("action", set.create_action::<xr::Posef>("aim", "Brush tip (aim pose)", &hands))?;
        let p = |s: &str| call("path", instance.string_to_path(s));
        // Each profile: (profile, per hand: [(action kind, component)]).
        type Kind = u8; // 0 trigger, 1 grip, 2 stick, 3 primary, 4 secondary, 5 aim
        let profiles: [(&str, &[(Kind, &str)], &[(Kind, &str)]); 4] = [
            (
                "/interaction_profiles/khr/simple_controller",
                &[(0, "select/click"), (3, "menu/click"), (5, "aim/pose")],
                &[(0, "select/click"), (3, "menu/click"), (5, "aim/pose")],
            ),
            (
                "/interaction_profiles/valve/index_controller",
                &[(0, "trigger/value"), (1, "squeeze/value"), (2, "thumbstick"), (3, "a/click"), (4, "b/click"), (5, "aim/pose")],
                &[(0, "trigger/value"), (1, "squeeze/value"), (2, "thumbstick"), (3, "a/click"), (4, "b/click"), (5, "aim/pose")],
            ),
            (
                "/interaction_profiles/oculus/touch_controller",
                &[(0, "trigger/value"), (1, "squeeze/value"), (2, "thumbstick"), (3, "x/click"), (4, "y/click"), (5, "aim/pose")],
                &[(0, "trigger/value"), (1, "squeeze/value"), (2, "thumbstick"), (3, "a/click"), (4, "b/click"), (5, "aim/pose")],
            ),
            (
                "/interaction_profiles/htc/vive_controller",
                &[(0, "trigger/value"), (1, "squeeze/click"), (2, "trackpad"), (3, "menu/click"), (5, "aim/pose")],
                &[(0, "trigger/value"), (1, "squeeze/click"), (2, "trackpad"), (3, "menu/click"), (5, "aim/pose")],
            ),
        ];
        for (profile, l, r) in profiles {
            let mut paths = Vec::new();
            for (hand, list) in [("left", l), ("right", r)] {
                for &(kind, comp) in list {
                    paths.push((kind, p(&format!("/user/hand/{hand}/input/{comp}"))?));
                }
            }
            let bindings: Vec<xr::Binding> = paths
                .iter()
                .map(|&(kind, path)| match kind {
                    0 => xr::Binding::new(&trigger, path),
                    1 => xr::Binding::new(&grip, path),
                    2 => xr::Binding::new(&stick, path),
                    3 => xr::Binding::new(&primary, path),
                    4 => xr::Binding::new(&secondary, path),
                    _ => xr::Binding::new(&aim, path),
                })
                .collect();
            // A runtime that does not know a profile refuses it: the others
            // still apply.
            let _ = instance.suggest_interaction_profile_bindings(p(profile)?, &bindings);
        }
        call("attaching the actions", session.attach_action_sets(&[&set]))?;
        let mut spaces = Vec::new();
        for h in hands {
            spaces.push(call("hand space", aim.create_space(session, h, xr::Posef::IDENTITY))?);
        }
        Ok(Controls { set, trigger, grip, stick, primary, secondary, aim, hands, spaces })
    }

    /// Both hands' states at `time` in `base`.
    pub fn read<G: xr::Graphics>(&self, session: &xr::Session<G>, base: &xr::Space, time: xr::Time) -> Result<[Hand; 2], XrError> {
        call("syncing the actions", session.sync_actions(&[(&self.set).into()]))?;
        let mut out = [Hand::default(); 2];
        for (k, h) in out.iter_mut().enumerate() {
            let path = self.hands[k];
            let loc = call("locating a hand", self.spaces[k].locate(base, time))?;
            let valid = xr::SpaceLocationFlags::POSITION_VALID | xr::SpaceLocationFlags::ORIENTATION_VALID;
            if call("aim state", self.aim.is_active(session, path))? && loc.location_flags.contains(valid) {
                h.pose = Some(crate::pose_of(&loc.pose));
            }
            h.trigger = call("trigger", self.trigger.state(session, path))?.current_state;
            h.grip = call("grip", self.grip.state(session, path))?.current_state;
            let s = call("stick", self.stick.state(session, path))?.current_state;
            h.stick = [s.x, s.y];
            h.primary = call("primary", self.primary.state(session, path))?.current_state;
            h.secondary = call("secondary", self.secondary.state(session, path))?.current_state;
        }
        Ok(out)
    }
}

/// Scripted controller states: for each rendered frame number, the hands'
/// states from that frame on (a state holds until a later line changes
/// it). One JSON object per line:
///
/// `{"frame": 12, "hand": "right", "pose": [x, y, z, qx, qy, qz, qw],
///   "trigger": 0.8, "grip": 0, "stick": [0, 0], "primary": false,
///   "secondary": false}`
///
/// Positions are metres from where the head was at the first frame,
/// orientations in the session's space; every field but `frame` and
/// `hand` is optional (unchanged).
pub struct Script {
    changes: BTreeMap<u64, Vec<(usize, serde_json::Value)>>,
    state: [Hand; 2],
}

impl Script {
    pub fn load(path: &Path) -> Result<Script, XrError> {
        let text = std::fs::read_to_string(path).map_err(|e| XrError::Setup(format!("{}: {e}", path.display())))?;
        let mut changes: BTreeMap<u64, Vec<(usize, serde_json::Value)>> = BTreeMap::new();
        for (i, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
            let bad = |m: &str| XrError::Setup(format!("{}: line {}: {m}", path.display(), i + 1));
            let v: serde_json::Value = serde_json::from_str(line).map_err(|e| bad(&e.to_string()))?;
            let frame = v.get("frame").and_then(|f| f.as_u64()).ok_or_else(|| bad("\"frame\" must be a frame number"))?;
            let hand = match v.get("hand").and_then(|h| h.as_str()) {
                Some("left") => LEFT,
                Some("right") => RIGHT,
                _ => return Err(bad("\"hand\" must be \"left\" or \"right\"")),
            };
            if let Some(p) = v.get("pose") {
                let ok = p.as_array().is_some_and(|a| a.len() == 7 && a.iter().all(|x| x.as_f64().is_some_and(f64::is_finite)));
                if !ok {
                    return Err(bad("\"pose\" must be 7 finite numbers: x, y, z, qx, qy, qz, qw"));
                }
            }
            for key in ["trigger", "grip"] {
                if let Some(x) = v.get(key)
                    && !x.as_f64().is_some_and(|x| (0.0..=1.0).contains(&x))
                {
                    return Err(bad(&format!("\"{key}\" must be in [0, 1]")));
                }
            }
            changes.entry(frame).or_default().push((hand, v));
        }
        Ok(Script { changes, state: [Hand::default(); 2] })
    }

    /// The hands at rendered frame `frame` (0-based), poses placed relative
    /// to `head0`.
    pub fn at(&mut self, frame: u64, head0: DVec3) -> [Hand; 2] {
        if let Some(list) = self.changes.get(&frame) {
            for (hand, v) in list {
                let h = &mut self.state[*hand];
                if let Some(p) = v.get("pose").and_then(|p| p.as_array()) {
                    let f: Vec<f64> = p.iter().map(|x| x.as_f64().unwrap_or(0.0)).collect();
                    h.pose = Some((head0 + DVec3::new(f[0], f[1], f[2]), DQuat::from_xyzw(f[3], f[4], f[5], f[6]).normalize()));
                }
                let num = |k: &str| v.get(k).and_then(|x| x.as_f64()).map(|x| x as f32);
                if let Some(x) = num("trigger") {
                    h.trigger = x;
                }
                if let Some(x) = num("grip") {
                    h.grip = x;
                }
                if let Some(s) = v.get("stick").and_then(|s| s.as_array()) {
                    h.stick = [0, 1].map(|i| s.get(i).and_then(|x| x.as_f64()).unwrap_or(0.0).clamp(-1.0, 1.0) as f32);
                }
                if let Some(b) = v.get("primary").and_then(|b| b.as_bool()) {
                    h.primary = b;
                }
                if let Some(b) = v.get("secondary").and_then(|b| b.as_bool()) {
                    h.secondary = b;
                }
            }
        }
        self.state
    }

    /// The last frame the script changes anything at.
    pub fn last_frame(&self) -> u64 {
        self.changes.keys().next_back().copied().unwrap_or(0)
    }
}
