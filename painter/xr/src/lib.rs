//! OpenXR for the painter (docs/vr.md). Today: finding the runtime and the
//! headset, and saying exactly what is missing when there is none, which
//! `octopaint xr-info` prints and the VR session will start from.
//!
//! The OpenXR loader (`libopenxr_loader.so.1` on Linux, Debian's
//! `libopenxr-loader1`; `openxr_loader.dll` on Windows, shipped beside
//! `octopaint.exe` in the Windows package) is loaded at run time, so the
//! painter runs, and says why VR is unavailable, on machines without it.
//! [`platform`] holds what an artist is told to install on each system.

use openxr as xr;

mod frame;
pub mod gestures;
pub mod headset;
pub mod hud;
pub mod input;
pub mod placement;
pub mod platform;
mod setup;

/// An OpenXR pose (f32, room metres) as a position and a unit rotation in
/// f64.
pub(crate) fn pose_of(pose: &openxr::Posef) -> (glam::DVec3, glam::DQuat) {
    let (p, o) = (pose.position, pose.orientation);
    (
        glam::DVec3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)),
        glam::DQuat::from_xyzw(f64::from(o.x), f64::from(o.y), f64::from(o.z), f64::from(o.w)).normalize(),
    )
}

/// What the runtime reports about itself and its headset.
#[derive(Debug, Clone)]
pub struct XrInfo {
    pub runtime: String,
    pub runtime_version: String,
    pub system: String,
    pub vendor_id: u32,
    pub orientation_tracking: bool,
    pub position_tracking: bool,
    /// Recommended and largest image size per eye, and sample counts.
    pub views: Vec<ViewInfo>,
    /// Whether the runtime offers XR_KHR_vulkan_enable2 (what the painter
    /// renders through), and the Vulkan versions it accepts.
    pub vulkan_enable2: bool,
    pub vulkan_min: Option<String>,
    pub vulkan_max: Option<String>,
    pub blend_modes: Vec<String>,
}

#[derive(Debug, Clone, Copy)]
pub struct ViewInfo {
    pub recommended: [u32; 2],
    pub max: [u32; 2],
    pub samples: u32,
}

/// Why there is no VR here.
#[derive(Debug, thiserror::Error)]
pub enum XrError {
    #[error("no OpenXR loader ({help}): {0}", help = platform::LOADER_HELP)]
    NoLoader(String),
    #[error("no OpenXR runtime is running or installed ({help}; XR_RUNTIME_JSON names one explicitly)", help = platform::RUNTIME_HELP)]
    NoRuntime,
    #[error("the OpenXR runtime has no headset connected (XR_ERROR_FORM_FACTOR_UNAVAILABLE)")]
    NoHeadset,
    #[error("OpenXR: {what}: {result}")]
    Call { what: &'static str, result: xr::sys::Result },
    #[error("{0}")]
    Setup(String),
    /// VR is not built for this system (macOS).
    #[error("{0}")]
    Unsupported(&'static str),
}

impl XrError {
    /// This machine has no VR (no loader, runtime or headset, or a system
    /// without VR): callers say so and may open the desktop window, rather
    /// than report a failure.
    pub fn is_no_vr(&self) -> bool {
        matches!(self, XrError::NoLoader(_) | XrError::NoRuntime | XrError::NoHeadset | XrError::Unsupported(_))
    }
}

pub(crate) fn call<T>(what: &'static str, r: Result<T, xr::sys::Result>) -> Result<T, XrError> {
    r.map_err(|result| match result {
        xr::sys::Result::ERROR_RUNTIME_UNAVAILABLE | xr::sys::Result::ERROR_RUNTIME_FAILURE => XrError::NoRuntime,
        xr::sys::Result::ERROR_FORM_FACTOR_UNAVAILABLE => XrError::NoHeadset,
        result => XrError::Call { what, result },
    })
}

fn version(v: xr::Version) -> String {
    format!("{}.{}.{}", v.major(), v.minor(), v.patch())
}

/// An instance for the painter with `extensions`.
pub(crate) fn create_instance(entry: &xr::Entry, extensions: &xr::ExtensionSet) -> Result<xr::Instance, XrError> {
    let app = xr::ApplicationInfo {
        application_name: "octopaint",
        application_version: 1,
        engine_name: "octopaint",
        engine_version: 1,
        api_version: xr::Version::new(1, 0, 0),
    };
    call("creating an instance", entry.create_instance(&app, extensions, &[], &()))
}

/// Load the loader, create an instance and find the headset.
pub fn probe() -> Result<XrInfo, XrError> {
    // SAFETY: loading the system's OpenXR loader runs its initialisers;
    // it is the library the OpenXR specification names for this, and the
    // entry points are only used through the openxr crate's typed API.
    let entry = unsafe { xr::Entry::load(&()) }.map_err(|e| XrError::NoLoader(e.to_string()))?;
    let available = call("enumerating extensions", entry.enumerate_extensions())?;
    let mut wanted = xr::ExtensionSet::default();
    wanted.khr_vulkan_enable2 = available.khr_vulkan_enable2;
    let instance = create_instance(&entry, &wanted)?;
    let props = call("reading the runtime's properties", instance.properties())?;
    let system = call("finding the headset", instance.system(xr::FormFactor::HEAD_MOUNTED_DISPLAY))?;
    let sp = call("reading the headset's properties", instance.system_properties(system))?;
    let views = call("reading the stereo views", instance.enumerate_view_configuration_views(system, xr::ViewConfigurationType::PRIMARY_STEREO))?
        .into_iter()
        .map(|v| ViewInfo {
            recommended: [v.recommended_image_rect_width, v.recommended_image_rect_height],
            max: [v.max_image_rect_width, v.max_image_rect_height],
            samples: v.recommended_swapchain_sample_count,
        })
        .collect();
    let (vulkan_min, vulkan_max) = if available.khr_vulkan_enable2 {
        let r = call("reading the Vulkan requirements", instance.graphics_requirements::<xr::Vulkan>(system))?;
        (Some(version(r.min_api_version_supported)), Some(version(r.max_api_version_supported)))
    } else {
        (None, None)
    };
    let blend_modes = call("reading the blend modes", instance.enumerate_environment_blend_modes(system, xr::ViewConfigurationType::PRIMARY_STEREO))?
        .into_iter()
        .map(|m| format!("{m:?}"))
        .collect();
    Ok(XrInfo {
        runtime: props.runtime_name,
        runtime_version: version(props.runtime_version),
        system: sp.system_name,
        vendor_id: sp.vendor_id,
        orientation_tracking: sp.tracking_properties.orientation_tracking,
        position_tracking: sp.tracking_properties.position_tracking,
        views,
        vulkan_enable2: available.khr_vulkan_enable2,
        vulkan_min,
        vulkan_max,
        blend_modes,
    })
}
