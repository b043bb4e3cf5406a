//! `vesalius haptics`: the servo loop against the sandbox with the simulated stylus prints
//! every figure, finite, with a force that is felt and never above the device's limit. The
//! Phantom (OpenHaptics HD, pushed by its scheduler) and the Falcon (DHD, pulled by our thread)
//! run the same loop through their vendor libraries, here the fakes `xr-bindings` builds, found
//! the way users' are (LD_LIBRARY_PATH); without a library, or when the device faults, the
//! command fails cleanly (exit 1, a message naming the library or the fault).
//! Figures are checked for sense, not speed: the machine running the tests is shared.

mod common;
use common::{bin, text};
use vesalius::haptics::DeviceKind;

const KEYS: [&str; 6] = [
    "rate_hz",
    "period_p50_error_ms",
    "period_p99_error_ms",
    "max_force_n",
    "clamps",
    "stalls",
];

#[test]
fn the_simulated_stylus_reports_every_figure_as_json() {
    let o = bin()
        .args(["haptics", "--device", "sim", "--seconds", "1", "--json"])
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    for key in KEYS.iter().chain(&["ticks", "sim_steps", "limit_force_n"]) {
        let x = v[key].as_f64().unwrap_or(f64::NAN);
        assert!(x.is_finite() && x >= 0.0, "{key}: {v}");
    }
    let limit = DeviceKind::Simulated.table_limits().max_force_n;
    let max = v["max_force_n"].as_f64().unwrap_or(f64::NAN);
    assert!(
        max > 0.0 && max <= limit,
        "max_force_n {max} (limit {limit}): {v}"
    );
    assert_eq!(v["limit_force_n"].as_f64(), Some(limit));
    // It ran the loop and the procedure (counts, not rates).
    assert!(v["ticks"].as_u64().unwrap_or(0) > 100, "{v}");
    assert!(v["sim_steps"].as_u64().unwrap_or(0) > 10, "{v}");
    assert!(v["rate_hz"].as_f64().unwrap_or(0.0) > 0.0, "{v}");
    assert!(v["clamps"].is_u64() && v["stalls"].is_u64(), "{v}");
}

#[test]
fn plain_text_is_one_key_and_value_a_line() {
    let o = bin()
        .args(["haptics", "--device", "sim", "--seconds", "0.3"])
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    for key in KEYS {
        let line = out
            .lines()
            .find(|l| l.split(' ').next() == Some(key))
            .unwrap_or_else(|| panic!("no {key} in {out}"));
        let value: Option<f64> = line.split(' ').nth(1).and_then(|v| v.parse().ok());
        assert!(value.is_some_and(f64::is_finite), "{line}");
        assert_eq!(line.split(' ').count(), 2, "{line}");
    }
}

/// The command with the fake vendor libraries on the loader's path and no override.
fn with_fakes(args: &[&str], knobs: &[(&str, &str)]) -> std::process::Output {
    let dir = xr_bindings::haptics::fake_library_dir();
    let mut c = bin();
    c.args(args)
        .env("LD_LIBRARY_PATH", dir)
        .env_remove("VESALIUS_LIBHD")
        .env_remove("VESALIUS_LIBDHD");
    for (k, v) in knobs {
        c.env(k, v);
    }
    c.output().expect("runs")
}

#[test]
fn vendor_devices_fail_with_a_message_naming_their_library() {
    for (device, library) in [("phantom", "libHD"), ("falcon", "libdhd")] {
        let o = bin()
            .args(["haptics", "--device", device, "--seconds", "1"])
            .env_remove("LD_LIBRARY_PATH")
            .env_remove("VESALIUS_LIBHD")
            .env_remove("VESALIUS_LIBDHD")
            .output()
            .expect("runs");
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(library) && err.contains(device), "{err}");
        assert!(err.contains("LD_LIBRARY_PATH"), "{err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(o.stdout.is_empty());
    }
}

/// Each vendor path runs the servo at its rate against the sandbox with the stylus held 1 mm
/// into the block (the device's origin is 15 mm above the block's top) and never goes past its
/// device's limit. Whether that stylus feels the block is not asserted: the fakes hold it
/// still at one depth from the first tick, and the start-up ramp rightly keeps the gain at
/// zero while the force it would render is not small (the simulated stylus, which comes down
/// from above, shows a felt force).
#[test]
fn vendor_devices_run_the_servo_through_their_libraries() {
    for (device, knob, value, kind) in [
        (
            "phantom",
            "FAKE_HD_POSITION_MM",
            "0,-16,0",
            DeviceKind::PhantomOmni,
        ),
        (
            "falcon",
            "FAKE_DHD_POSITION_M",
            "0,-0.016,0",
            DeviceKind::Falcon,
        ),
    ] {
        let o = with_fakes(
            &["haptics", "--device", device, "--seconds", "1.5", "--json"],
            &[(knob, value)],
        );
        assert_eq!(o.status.code(), Some(0), "{device}: {}", text(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
        let limit = kind.table_limits().max_force_n;
        assert_eq!(v["limit_force_n"].as_f64(), Some(limit), "{device}: {v}");
        let max = v["max_force_n"].as_f64().unwrap_or(f64::NAN);
        assert!((0.0..=limit).contains(&max), "{device}: max {max} N: {v}");
        assert!(v["ticks"].as_u64().unwrap_or(0) > 100, "{device}: {v}");
        assert_eq!(v["non_finite"].as_u64(), Some(0), "{device}: {v}");
    }
}

/// A device that faults mid-session ends it: exit 1, the vendor's own words, no panic.
#[test]
fn a_device_fault_ends_the_session_with_an_error_naming_it() {
    for (device, knob, words) in [
        ("phantom", "FAKE_HD_FAULT_AFTER_TICKS", "HD_DEVICE_FAULT"),
        ("falcon", "FAKE_DHD_FAULT_AFTER_FORCES", "dhdSetForce"),
    ] {
        let o = with_fakes(
            &["haptics", "--device", device, "--seconds", "5"],
            &[(knob, "200")],
        );
        assert_eq!(o.status.code(), Some(1), "{device}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(words), "{device}: {err}");
        assert!(!err.contains("panicked"), "{device}: {err}");
    }
}

#[test]
fn bad_flags_are_usage_errors() {
    for args in [
        &["haptics"][..],
        &["haptics", "--device", "omni"],
        &["haptics", "--device", "sim", "--seconds", "0"],
        &["haptics", "--device", "sim", "--seconds", "-1"],
        &["haptics", "--device", "sim", "--procedure", "appendectomy"],
    ] {
        let o = bin().args(args).output().expect("runs");
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
    }
}
