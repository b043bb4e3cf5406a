//! The DHD bindings' real FFI path against the fake libdhd the build script compiles from
//! `tests/fake/fake_dhd.c` (same symbols and C types as libdhd.so): units, explicit device
//! ids, forces, the watchdog, return codes and typed errors.
//!
//! The fake keeps process-wide state, so every test holds `LOCK` and resets it first.

mod common;
use common::*;

use std::path::Path;
use std::time::Duration;

use xr_bindings::haptics::{DHD_DEVICE_FALCON, DhdDevice, ForceStatus, HapticsError};

#[test]
fn dhd_missing_library_is_named_and_the_override_is_honoured() {
    let _g = lock();
    let err = DhdDevice::open_from(Path::new("/nonexistent/vesalius-test/libdhd.so"))
        .expect_err("no library there");
    assert_mentions(
        &err.to_string(),
        &[
            "libdhd.so (Force Dimension SDK) was not found: install the Force Dimension SDK",
            "LD_LIBRARY_PATH",
            "VESALIUS_LIBDHD",
            "/nonexistent/vesalius-test/libdhd.so",
        ],
    );

    let err = with_env(
        "VESALIUS_LIBDHD",
        "/nonexistent/override/libdhd.so",
        DhdDevice::open,
    )
    .expect_err("the override names no file");
    assert!(
        matches!(
            err,
            HapticsError::LibraryMissing {
                library: "libdhd.so",
                ..
            }
        ),
        "{err:?}"
    );

    let fake = fake_dhd();
    fake.reset();
    let path = dhd_path();
    let dev = with_env(
        "VESALIUS_LIBDHD",
        path.to_str().expect("a UTF-8 path"),
        DhdDevice::open,
    )
    .expect("the override names the fake");
    assert_eq!(fake.get_int("is_open"), 1);
    drop(dev);
    assert_eq!(fake.get_int("is_open"), 0, "drop closes the device");
}

#[test]
fn dhd_queries_units_and_explicit_ids() {
    let _g = lock();
    let fake = fake_dhd();
    fake.reset();
    fake.set_int("set_open_id", 2);
    fake.set_xyz("set_position_m", [0.0125, -0.02, 0.031]);
    fake.set_int("set_buttons", 0b101);
    let mut dev = DhdDevice::open_from(&dhd_path()).expect("opens");
    assert_eq!(dev.id(), 2);
    assert_eq!(dev.system_name().expect("a name"), "Falcon");
    assert_eq!(dev.system_type().expect("a type"), DHD_DEVICE_FALCON);
    assert_eq!(dev.max_force_n().expect("exported"), Some(8.0));
    assert_eq!(
        dev.position_m().expect("a position"),
        [0.0125, -0.02, 0.031],
        "metres pass unchanged"
    );
    assert_eq!(dev.buttons(), 0b101);

    dev.set_max_force_n(Some(5.0)).expect("sets");
    assert_eq!(fake.get_f64("max_force"), 5.0);
    dev.set_max_force_n(None).expect("removes the limit");
    assert_eq!(fake.get_f64("max_force"), -1.0);
    assert_eq!(
        dev.max_force_n().expect("exported"),
        None,
        "negative is no limit"
    );
    let err = dev
        .set_max_force_n(Some(f64::NAN))
        .expect_err("NaN refused");
    assert!(
        matches!(err, HapticsError::InvalidArgument { .. }),
        "{err:?}"
    );
    assert_eq!(
        fake.calls("dhdSetMaxForce"),
        2,
        "a refused value is not sent"
    );

    assert_eq!(fake.get_int("force_enabled"), -1);
    dev.enable_force(true).expect("enables");
    assert_eq!(fake.get_int("force_enabled"), 1);
    dev.enable_force(false).expect("disables");
    assert_eq!(fake.get_int("force_enabled"), 0);

    dev.close().expect("closes");
    assert_eq!(fake.get_int("is_open"), 0);
    assert_eq!(fake.calls("dhdClose"), 1);
    assert_eq!(
        fake.get_long("default_id_calls"),
        0,
        "every call named the device's ID"
    );
}

#[test]
fn dhd_forces_watchdog_and_return_codes() {
    let _g = lock();
    let fake = fake_dhd();
    fake.reset();
    let mut dev = DhdDevice::open_from(&dhd_path()).expect("opens");

    assert_eq!(dev.set_watchdog(Duration::from_millis(1)).expect("sets"), 8);
    assert_eq!(fake.get_int("watchdog"), 8, "1 ms is 8 units of 125 us");
    assert_eq!(
        dev.set_watchdog(Duration::from_nanos(2_000_001))
            .expect("sets"),
        17
    );
    assert_eq!(fake.get_int("watchdog"), 17, "rounded up");
    let err = dev
        .set_watchdog(Duration::from_millis(32))
        .expect_err("too long");
    assert!(
        matches!(err, HapticsError::InvalidArgument { .. }),
        "{err:?}"
    );
    assert_eq!(fake.get_int("watchdog"), 17, "a refused value is not sent");

    assert_eq!(
        dev.set_force_n([1.5, -2.0, 0.25]).expect("sent"),
        ForceStatus::default()
    );
    assert_eq!(fake.last_force(), [1.5, -2.0, 0.25]);
    let s = dev.set_force_n([10.0, 0.0, 0.0]).expect("sent");
    assert_eq!(
        s,
        ForceStatus {
            saturated: true,
            timeguard: false
        }
    );
    assert_eq!(fake.last_force(), [8.0, 0.0, 0.0]);
    fake.set_int("set_timeguard", 1);
    let s = dev
        .set_force_n([1.0, 0.0, 0.0])
        .expect("a timeguard is not an error");
    assert_eq!(
        s,
        ForceStatus {
            saturated: false,
            timeguard: true
        }
    );
    fake.set_int("set_timeguard", 0);
    let err = dev
        .set_force_n([f64::NAN, 1.0, 0.0])
        .expect_err("NaN refused");
    assert!(
        matches!(err, HapticsError::NonFiniteForce { .. }),
        "{err:?}"
    );
    assert_eq!(fake.last_force(), [0.0; 3], "zero force sent instead");

    // Every dhdSetForce after the 5th fails.
    fake.set_int("set_fault_after_forces", 5);
    dev.set_force_n([0.5, 0.0, 0.0]).expect("the 5th is served");
    let err = dev.set_force_n([0.5, 0.0, 0.0]).expect_err("the 6th fails");
    match &err {
        HapticsError::DhdCall {
            call: "dhdSetForce",
            message,
        } => {
            assert!(message.contains("USB transfer failed"), "{message}");
        }
        other => panic!("expected DhdCall, got {other:?}"),
    }
    assert_eq!(
        fake.force_log(),
        vec![
            [1.5, -2.0, 0.25],
            [8.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0; 3],
            [0.5, 0.0, 0.0]
        ]
    );
    assert_eq!(fake.get_long("default_id_calls"), 0);
    drop(dev);
}

#[test]
fn dhd_open_failure_is_typed() {
    let _g = lock();
    let fake = fake_dhd();
    fake.reset();
    fake.set_int("set_fail_open", 1);
    let err = DhdDevice::open_from(&dhd_path()).expect_err("open fails");
    match &err {
        HapticsError::DhdOpen { message } => assert_eq!(message, "no device found (fake libdhd)"),
        other => panic!("expected DhdOpen, got {other:?}"),
    }
    assert_mentions(&err.to_string(), &["no device found (fake libdhd)"]);

    with_env("FAKE_DHD_FAIL_OPEN", "1", || fake.reset());
    assert!(matches!(
        DhdDevice::open_from(&dhd_path()),
        Err(HapticsError::DhdOpen { .. })
    ));
    fake.reset();
    let dev = DhdDevice::open_from(&dhd_path()).expect("opens once the knob is off");
    drop(dev);
    assert_eq!(fake.calls("dhdOpen"), 1);
    assert_eq!(fake.calls("dhdClose"), 1);
}
