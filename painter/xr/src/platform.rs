//! What an artist needs for VR on each system, in the words the painter's
//! messages use (`octopaint xr-info`, `octopaint vr`; docs/vr.md).

/// Where the OpenXR loader comes from.
#[cfg(windows)]
pub const LOADER_HELP: &str = "openxr_loader.dll, which the Windows package ships beside octopaint.exe: unpack the whole zip, or put the Khronos loader DLL next to the executable or on the PATH";
#[cfg(target_os = "macos")]
pub const LOADER_HELP: &str = NO_VR_HERE;
#[cfg(not(any(windows, target_os = "macos")))]
pub const LOADER_HELP: &str = "libopenxr_loader.so.1; Debian and Ubuntu: apt-get install libopenxr-loader1";

/// Where an OpenXR runtime comes from.
#[cfg(windows)]
pub const RUNTIME_HELP: &str = "start SteamVR or the Meta Quest Link app and set it as the active OpenXR runtime in its settings";
#[cfg(not(windows))]
pub const RUNTIME_HELP: &str = "install and start one: Monado's monado-service, SteamVR, ...";

/// Said after "the runtime has no XR_KHR_vulkan_enable2".
#[cfg(windows)]
pub const NO_VULKAN_BINDING_HELP: &str =
    " (Windows Mixed Reality's own runtime offers Direct3D only: run its headsets through SteamVR, set as the OpenXR runtime)";
#[cfg(not(windows))]
pub const NO_VULKAN_BINDING_HELP: &str = "";

/// macOS: no OpenXR runtime exists for it and wgpu has no Vulkan there, so
/// the painter is the desktop window only.
#[cfg(target_os = "macos")]
pub const NO_VR_HERE: &str = "VR is not available on macOS (no OpenXR runtime exists for it): octopaint window paints on the desktop";
