//! The simulated runtime loaded by the real Khronos OpenXR loader (`libopenxr-loader1`; CI
//! installs it with `libopenxr-utils`), through a runtime manifest named by `XR_RUNTIME_JSON`,
//! exactly as SteamVR or Monado are loaded.

use openxr as xr;
use xr::sys::Handle as _;
mod common;

use std::path::PathBuf;
use vesalius_sim_runtime::{CORE_FUNCTIONS, EYE_SIZE, RUNTIME_NAME, SYSTEM_NAME, manifest};

/// The manifest in a scratch folder of its own, and the folder (removed when the test passes).
fn write_manifest(name: &str) -> (common::Scratch, PathBuf) {
    let dir = common::temp_dir(name);
    let path = dir.join("vesalius_sim_runtime.json");
    std::fs::write(
        &path,
        manifest(&common::runtime_library().display().to_string()),
    )
    .expect("manifest");
    (dir, path)
}

#[test]
fn the_khronos_loader_lists_the_runtime() {
    let (_dir, m) = write_manifest("list");
    let out = std::process::Command::new("openxr_runtime_list")
        .env("XR_RUNTIME_JSON", &m)
        .output()
        .expect("openxr_runtime_list (apt-get install libopenxr-utils)");
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    // Loader 1.0.20's tool creates an instance on the runtime and prints its system.
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains(SYSTEM_NAME) && text.contains("systemId: 0x1"),
        "{text}"
    );
}

#[test]
fn an_app_creates_an_instance_and_finds_a_stereo_hmd_through_the_loader() {
    let (_dir, m) = write_manifest("instance");
    // SAFETY: this is the only test in this binary that touches the environment, and it sets
    // the variable before any loader call reads it.
    unsafe { std::env::set_var("XR_RUNTIME_JSON", &m) };
    // SAFETY: the Debian package's loader conforms to the OpenXR specification.
    let entry = unsafe { xr::Entry::load(&()) }
        .expect("libopenxr_loader.so.1 (apt-get install libopenxr-loader1)");
    let instance = entry
        .create_instance(
            &xr::ApplicationInfo {
                application_name: "vesalius-test",
                application_version: 1,
                engine_name: "vesalius",
                engine_version: 1,
                api_version: xr::Version::new(1, 0, 0),
            },
            &xr::ExtensionSet::default(),
            &[],
            &(),
        )
        .expect("instance through the loader");
    let props = instance.properties().expect("instance properties");
    assert_eq!(props.runtime_name, RUNTIME_NAME);
    let system = instance
        .system(xr::FormFactor::HEAD_MOUNTED_DISPLAY)
        .expect("an HMD");
    let sp = instance
        .system_properties(system)
        .expect("system properties");
    assert_eq!(sp.system_name, SYSTEM_NAME);
    assert!(sp.tracking_properties.position_tracking);
    let configs = instance
        .enumerate_view_configurations(system)
        .expect("view configurations");
    assert_eq!(configs, [xr::ViewConfigurationType::PRIMARY_STEREO]);
    let views = instance
        .enumerate_view_configuration_views(system, xr::ViewConfigurationType::PRIMARY_STEREO)
        .expect("views");
    assert_eq!(views.len(), 2);
    for v in &views {
        assert_eq!(
            (
                v.recommended_image_rect_width,
                v.recommended_image_rect_height
            ),
            EYE_SIZE
        );
    }
    // Paths round-trip and malformed ones are refused.
    let p = instance
        .string_to_path("/user/hand/right/input/aim/pose")
        .expect("path");
    assert_eq!(
        instance.path_to_string(p).expect("string"),
        "/user/hand/right/input/aim/pose"
    );
    assert!(instance.string_to_path("/user/Hand//x").is_err());
    // No event yet.
    let mut buf = xr::EventDataBuffer::new();
    assert!(instance.poll_event(&mut buf).expect("poll").is_none());
    // A core function not implemented yet answers XR_ERROR_FUNCTION_UNSUPPORTED, not a crash.
    let blend = instance
        .enumerate_environment_blend_modes(system, xr::ViewConfigurationType::PRIMARY_STEREO)
        .expect("blend modes");
    assert_eq!(blend, [xr::EnvironmentBlendMode::OPAQUE]);
    // Action sets are made; a malformed name is refused.
    assert!(instance.create_action_set("tools", "Tools", 0).is_ok());
    assert_eq!(
        instance.create_action_set("Tools!", "Tools", 0).err(),
        Some(xr::sys::Result::ERROR_NAME_INVALID)
    );
    // A core function the runtime leaves out (localized input names) answers
    // XR_ERROR_FUNCTION_UNSUPPORTED through the loader, not a crash.
    let mut count = 0u32;
    // SAFETY: the stub reads none of its arguments.
    let r = unsafe {
        (instance.fp().get_input_source_localized_name)(
            xr::sys::Session::from_raw(0),
            std::ptr::null(),
            0,
            &mut count,
            std::ptr::null_mut(),
        )
    };
    assert_eq!(r, xr::sys::Result::ERROR_FUNCTION_UNSUPPORTED);
    assert_eq!(CORE_FUNCTIONS.len(), 55);
}
