//! The HD bindings' real FFI path against the fake libHD the build script compiles from
//! `tests/fake/fake_hd.c` (same symbols and C types as libHD.so): units, the servo callback
//! protocol, two devices on the one scheduler, and typed errors.
//!
//! The fake keeps process-wide state, so every test holds `LOCK` and resets it first. No test
//! asserts timing: waits are for counts, bounded only so a broken build fails instead of
//! hanging.

mod common;
use common::*;

use std::ffi::{c_char, c_int, c_uint};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError, mpsc};
use std::time::Duration;

use xr_bindings::haptics::{HapticsError, HdCommand, HdDevice, HdErrorInfo, HdState};

fn hd_enabled(fake: &Fake, cap: c_uint) -> c_int {
    // SAFETY: `int fake_hd_is_enabled(unsigned int)`.
    unsafe { fake.sym::<unsafe extern "C" fn(c_uint) -> c_int>("is_enabled")(cap) }
}

/// The name the last hdInitDevice got, `None` for HD_DEFAULT_DEVICE (NULL).
fn hd_init_name(fake: &Fake) -> Option<String> {
    let mut buf = [0u8; 128];
    // SAFETY: `int fake_hd_init_name(char* out, int cap)`, which writes at most `cap` bytes
    // including the NUL.
    let given = unsafe {
        fake.sym::<unsafe extern "C" fn(*mut c_char, c_int) -> c_int>("init_name")(
            buf.as_mut_ptr().cast(),
            128,
        )
    };
    let end = buf.iter().position(|b| *b == 0).unwrap_or(buf.len());
    (given != 0).then(|| String::from_utf8_lossy(&buf[..end]).into_owned())
}

fn open_hd(fake: &Fake) -> HdDevice {
    fake.reset();
    HdDevice::open_from(&hd_path(), None).expect("the fake HD device opens")
}

fn stop_after(n: u64, force_n: [f64; 3]) -> impl FnMut(&HdState) -> HdCommand + Send + 'static {
    move |s| {
        if s.tick >= n {
            HdCommand::Stop
        } else {
            HdCommand::Continue { force_n }
        }
    }
}

#[test]
fn hd_missing_library_is_named_and_the_override_is_honoured() {
    let _g = lock();
    let missing = Path::new("/nonexistent/vesalius-test/libHD.so");
    let err = HdDevice::open_from(missing, None).expect_err("no library there");
    assert!(
        matches!(
            &err,
            HapticsError::LibraryMissing {
                library: "libHD.so",
                env_var: "VESALIUS_LIBHD",
                ..
            }
        ),
        "{err:?}"
    );
    assert_mentions(
        &err.to_string(),
        &[
            "libHD.so (3D Systems OpenHaptics) was not found: install OpenHaptics for Linux",
            "LD_LIBRARY_PATH",
            "VESALIUS_LIBHD",
            "/nonexistent/vesalius-test/libHD.so",
        ],
    );

    // The override is the only file tried when set.
    let err = with_env("VESALIUS_LIBHD", "/nonexistent/override/libHD.so", || {
        HdDevice::open(None)
    })
    .expect_err("the override names no file");
    assert_mentions(&err.to_string(), &["/nonexistent/override/libHD.so"]);

    let fake = fake_hd();
    fake.reset();
    let path = hd_path();
    let dev = with_env(
        "VESALIUS_LIBHD",
        path.to_str().expect("a UTF-8 path"),
        || HdDevice::open(None),
    )
    .expect("the override names the fake");
    assert_eq!(fake.calls("hdInitDevice"), 1);
    drop(dev);
    assert_eq!(fake.calls("hdDisableDevice"), 1, "drop disables the device");
}

#[test]
fn hd_units_nominal_values_and_forces_cross_the_ffi_unchanged() {
    let _g = lock();
    let fake = fake_hd();
    fake.reset();
    fake.set_xyz("set_position_mm", [12.5, -3.0, 40.0]);
    fake.set_xyz("set_velocity_mm_s", [100.0, 0.0, -50.0]);
    fake.set_int("set_buttons", 0b10);
    let mut dev = HdDevice::open_from(&hd_path(), None).expect("opens");
    assert_eq!(
        hd_init_name(&fake),
        None,
        "None is HD_DEFAULT_DEVICE (NULL)"
    );
    assert!((dev.nominal_max_force_n() - 3.3).abs() < 1e-12);
    assert!(
        (dev.nominal_max_stiffness_n_per_m() - 700.0).abs() < 1e-9,
        "0.7 N/mm is 700 N/m"
    );

    assert_eq!(hd_enabled(&fake, 0x4000), 0);
    dev.enable_force_output().expect("enables");
    assert_eq!(hd_enabled(&fake, 0x4000), 1, "HD_FORCE_OUTPUT enabled");

    let (tx, rx) = mpsc::channel::<HdState>();
    dev.start(move |s| {
        let _ = tx.send(*s);
        HdCommand::Continue {
            force_n: [1.5, -0.25, 0.0],
        }
    })
    .expect("starts");
    wait_for("50 servo ticks", || dev.servo_status().ticks >= 50);
    let status = dev.stop().expect("stops");
    assert!(
        !status.running && status.ticks >= 50 && status.first_error.is_none(),
        "{status:?}"
    );
    assert_eq!(fake.get_long("scheduler_rate"), 1000);

    let states: Vec<HdState> = rx.try_iter().collect();
    assert_eq!(states.len() as u64, status.ticks);
    for (i, s) in states.iter().enumerate() {
        assert_eq!(s.tick, i as u64 + 1);
        assert!(approx(s.position_m, [0.0125, -0.003, 0.04]), "{s:?}");
        assert!(approx(s.velocity_m_per_s, [0.1, 0.0, -0.05]), "{s:?}");
        assert_eq!(s.buttons, 0b10);
        assert_eq!(s.error, None);
    }
    let log = fake.force_log();
    assert_eq!(log.len() as u64, status.ticks, "one force per frame");
    assert!(log.iter().all(|f| *f == [1.5, -0.25, 0.0]), "{log:?}");
    assert_eq!(fake.get_long("protocol_errors"), 0);

    dev.close().expect("closes");
    assert_eq!(fake.get_int("open_devices"), 0);
}

#[test]
fn hd_servo_protocol_frames_stop_and_unschedule() {
    let _g = lock();
    let fake = fake_hd();
    let mut dev = open_hd(&fake);
    let calls = Arc::new(AtomicU64::new(0));

    // A callback that returns Stop on its 5th call is not called again, nor unscheduled.
    let c = Arc::clone(&calls);
    let mut inner = stop_after(5, [0.2, 0.0, 0.0]);
    dev.start(move |s| {
        c.fetch_add(1, Ordering::SeqCst);
        inner(s)
    })
    .expect("starts");
    wait_for("the callback to finish", || {
        !dev.servo_status().running && fake.get_int("active_callbacks") == 0
    });
    assert_eq!(calls.load(Ordering::SeqCst), 5);
    assert_eq!(fake.calls("hdBeginFrame"), 5);
    assert_eq!(fake.calls("hdEndFrame"), 5);
    let log = fake.force_log();
    assert_eq!(log.len(), 5);
    assert!(
        log[..4].iter().all(|f| *f == [0.2, 0.0, 0.0]) && log[4] == [0.0; 3],
        "{log:?}"
    );
    let status = dev.stop().expect("stops");
    assert_eq!(status.ticks, 5);
    assert_eq!(
        fake.calls("hdUnschedule"),
        0,
        "a finished callback is not unscheduled"
    );
    assert_eq!(fake.calls("hdStopScheduler"), 1);
    assert_eq!(fake.get_int("scheduler_running"), 0);

    // A callback that continues runs until stop(), which unschedules it; its force is clamped
    // to the nominal 3.3 N.
    let c = Arc::clone(&calls);
    dev.start(move |_| {
        c.fetch_add(1, Ordering::SeqCst);
        HdCommand::Continue {
            force_n: [10.0, 0.0, 0.0],
        }
    })
    .expect("starts again");
    wait_for("20 more ticks", || dev.servo_status().ticks >= 20);
    assert!(matches!(
        dev.start(|_| HdCommand::Stop),
        Err(HapticsError::ServoRunning)
    ));
    let status = dev.stop().expect("stops");
    assert_eq!(fake.calls("hdUnschedule"), 1);
    assert_eq!(fake.get_int("active_callbacks"), 0);
    assert_eq!(fake.get_int("scheduler_running"), 0);
    let total = calls.load(Ordering::SeqCst);
    assert_eq!(total, 5 + status.ticks);
    assert_eq!(fake.calls("hdBeginFrame"), fake.calls("hdEndFrame"));
    assert_eq!(fake.calls("hdBeginFrame") as u64, total);
    let ticks = fake.get_long("ticks");
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(
        fake.get_long("ticks"),
        ticks,
        "the scheduler thread stopped"
    );
    assert_eq!(
        calls.load(Ordering::SeqCst),
        total,
        "the callback is not called after stop()"
    );
    let log = fake.force_log();
    assert!(
        log[5..].iter().all(|f| approx(*f, [3.3, 0.0, 0.0])),
        "{:?}",
        &log[5..]
    );

    // A non-finite force is rendered as zero; start() after a finished callback needs no stop().
    dev.start(stop_after(3, [f64::NAN, 1.0, 0.0]))
        .expect("starts");
    wait_for("the callback to finish", || !dev.servo_status().running);
    dev.start(stop_after(1, [0.0; 3]))
        .expect("starts after a finished servo");
    wait_for("the callback to finish", || !dev.servo_status().running);
    dev.stop().expect("stops");
    let log = fake.force_log();
    assert_eq!(log.len() as u64, total + 4);
    assert!(
        log[log.len() - 4..].iter().all(|f| *f == [0.0; 3]),
        "{log:?}"
    );
    assert_eq!(fake.get_long("protocol_errors"), 0);
    assert_eq!(fake.calls("hdSetSchedulerRate"), 4);
}

impl Fake {
    fn set_device_position_mm(&self, hhd: u32, v: [f64; 3]) {
        // SAFETY: `void fake_hd_set_device_position_mm(unsigned int, double, double, double)`.
        unsafe {
            self.sym::<unsafe extern "C" fn(c_uint, f64, f64, f64)>("set_device_position_mm")(
                hhd, v[0], v[1], v[2],
            )
        }
    }

    fn device_last_force(&self, hhd: u32) -> [f64; 3] {
        let mut f = [0.0f64; 3];
        // SAFETY: `void fake_hd_device_last_force(unsigned int, double* out)`, which writes 3
        // doubles.
        unsafe {
            self.sym::<unsafe extern "C" fn(c_uint, *mut f64)>("device_last_force")(
                hhd,
                f.as_mut_ptr(),
            )
        };
        f
    }
}

/// A servo callback that pulls its stylus back to the device's origin with a 100 N/m spring
/// and keeps the last position it was given.
fn spring_to_origin(
    seen: Arc<Mutex<[f64; 3]>>,
) -> impl FnMut(&HdState) -> HdCommand + Send + 'static {
    move |s| {
        *seen.lock().unwrap_or_else(PoisonError::into_inner) = s.position_m;
        HdCommand::Continue {
            force_n: s.position_m.map(|x| -100.0 * x),
        }
    }
}

#[test]
fn hd_two_devices_share_the_one_scheduler_each_with_its_own_state() {
    let _g = lock();
    let fake = fake_hd();
    fake.reset();
    let mut left = HdDevice::open_from(&hd_path(), Some("Left")).expect("the first opens");
    let mut right = HdDevice::open_from(&hd_path(), Some("Right")).expect("the second opens");
    assert_eq!((left.handle(), right.handle()), (0, 1));
    fake.set_device_position_mm(0, [10.0, 0.0, 0.0]);
    fake.set_device_position_mm(1, [0.0, -20.0, 0.0]);
    let seen = [
        Arc::new(Mutex::new([0.0; 3])),
        Arc::new(Mutex::new([0.0; 3])),
    ];
    left.start(spring_to_origin(Arc::clone(&seen[0])))
        .expect("the first servo starts");
    right
        .start(spring_to_origin(Arc::clone(&seen[1])))
        .expect("the second servo starts beside it");
    wait_for("both servos to tick", || {
        left.servo_status().ticks >= 20 && right.servo_status().ticks >= 20
    });
    assert_eq!(fake.calls("hdStartScheduler"), 1, "one scheduler for both");
    assert_eq!(fake.get_int("active_callbacks"), 2);
    // Each callback saw its own stylus (mm -> m) and each device got its own force.
    let position = |k: usize| *seen[k].lock().unwrap_or_else(PoisonError::into_inner);
    assert!(approx(position(0), [0.01, 0.0, 0.0]), "{:?}", position(0));
    assert!(approx(position(1), [0.0, -0.02, 0.0]), "{:?}", position(1));
    assert!(approx(fake.device_last_force(0), [-1.0, 0.0, 0.0]));
    assert!(approx(fake.device_last_force(1), [0.0, 2.0, 0.0]));

    // Stopping one leaves the other running on the scheduler, and renders zero on the first.
    let status = left.stop().expect("the first stops");
    assert!(!status.running);
    assert_eq!(fake.get_int("scheduler_running"), 1);
    assert_eq!(fake.calls("hdStopScheduler"), 0);
    assert_eq!(fake.get_int("active_callbacks"), 1);
    assert_eq!(fake.device_last_force(0), [0.0; 3]);
    let (left_ticks, right_ticks) = (status.ticks, right.servo_status().ticks);
    wait_for("the second to tick on", || {
        right.servo_status().ticks >= right_ticks + 20
    });
    assert_eq!(
        left.servo_status().ticks,
        left_ticks,
        "the first is not called"
    );
    assert!(approx(fake.device_last_force(1), [0.0, 2.0, 0.0]));

    // The last one stops the scheduler; either may be started again.
    right.stop().expect("the second stops");
    assert_eq!(fake.calls("hdStopScheduler"), 1);
    assert_eq!(fake.get_int("scheduler_running"), 0);
    assert_eq!(fake.get_int("active_callbacks"), 0);
    left.start(stop_after(3, [0.0; 3])).expect("starts again");
    wait_for("the callback to finish", || !left.servo_status().running);
    left.stop().expect("stops");
    assert_eq!(fake.calls("hdStartScheduler"), 2);
    assert_eq!(fake.get_int("scheduler_running"), 0);
    assert_eq!(fake.get_long("protocol_errors"), 0);
    left.close().expect("closes");
    right.close().expect("closes");
    assert_eq!(fake.get_int("open_devices"), 0);
}

#[test]
fn hd_init_and_start_failures_are_typed() {
    let _g = lock();
    let fake = fake_hd();
    fake.reset();
    fake.set_int("set_fail_init", 0x0302);
    let err = HdDevice::open_from(&hd_path(), Some("Phantom 2")).expect_err("init fails");
    match &err {
        HapticsError::HdInit {
            device,
            code,
            name,
            message,
            ..
        } => {
            assert_eq!(
                (device.as_str(), *code, *name),
                ("Phantom 2", 0x0302, "HD_COMM_ERROR")
            );
            assert_eq!(
                message,
                "communication error: no device on the port (fake libHD)"
            );
        }
        other => panic!("expected HdInit, got {other:?}"),
    }
    assert_mentions(&err.to_string(), &["HD_COMM_ERROR", "0x0302", "Phantom 2"]);
    assert_eq!(hd_init_name(&fake).as_deref(), Some("Phantom 2"));

    // The knob the CLI tests use.
    with_env("FAKE_HD_FAIL_INIT", "1", || fake.reset());
    let err = HdDevice::open_from(&hd_path(), None).expect_err("init fails");
    assert!(
        matches!(err, HapticsError::HdInit { code: 0x0302, .. }),
        "{err:?}"
    );
    fake.reset();

    let err = HdDevice::open_from(&hd_path(), Some("a\0b")).expect_err("NUL in the name");
    assert!(
        matches!(err, HapticsError::InvalidDeviceName { .. }),
        "{err:?}"
    );
    assert_eq!(fake.calls("hdInitDevice"), 0);

    // hdStartScheduler failing: typed error, the callback unscheduled and never called.
    let mut dev = HdDevice::open_from(&hd_path(), None).expect("opens");
    fake.set_int("set_fail_start", 1);
    let calls = Arc::new(AtomicU64::new(0));
    let c = Arc::clone(&calls);
    let err = dev
        .start(move |_| {
            c.fetch_add(1, Ordering::SeqCst);
            HdCommand::Stop
        })
        .expect_err("the scheduler fails to start");
    assert!(
        matches!(
            err,
            HapticsError::HdCall {
                call: "hdStartScheduler",
                code: 0x0304,
                name: "HD_TIMER_ERROR",
                ..
            }
        ),
        "{err:?}"
    );
    assert_eq!(fake.calls("hdUnschedule"), 1);
    assert_eq!(fake.get_int("active_callbacks"), 0);
    assert_eq!(calls.load(Ordering::SeqCst), 0);
    fake.set_int("set_fail_start", 0);
    dev.start(stop_after(2, [0.0; 3]))
        .expect("the scheduler is free again");
    wait_for("the callback to finish", || !dev.servo_status().running);
    dev.close().expect("closes");
}

#[test]
fn hd_device_fault_reaches_the_callback_and_the_owner() {
    let _g = lock();
    let fake = fake_hd();
    let mut dev = open_hd(&fake);
    fake.set_int("set_fault_after_ticks", 10);
    let (tx, rx) = mpsc::channel::<HdState>();
    dev.start(move |s| {
        let _ = tx.send(*s);
        if s.error.is_some() {
            HdCommand::Stop
        } else {
            HdCommand::Continue {
                force_n: [0.5, 0.0, 0.0],
            }
        }
    })
    .expect("starts");
    wait_for("the callback to stop on the fault", || {
        !dev.servo_status().running
    });
    let states: Vec<HdState> = rx.try_iter().collect();
    assert_eq!(states.len(), 11, "the fault of frame 10 reaches call 11");
    assert!(states[..10].iter().all(|s| s.error.is_none()));
    let fault = HdErrorInfo {
        code: 0x0300,
        internal: 42,
    };
    assert_eq!(states[10].error, Some(fault));
    assert_eq!(fault.name(), Some("HD_DEVICE_FAULT"));
    assert_eq!(dev.servo_status().first_error, Some(fault));
    let err = dev.check_servo().expect_err("the owner sees the fault");
    assert!(
        matches!(&err, HapticsError::DeviceFault { code: 0x0300, name: "HD_DEVICE_FAULT", internal: 42, message } if message.contains("device fault")),
        "{err:?}"
    );
    assert!(err.to_string().contains("HD_DEVICE_FAULT (0x0300"), "{err}");
    dev.stop().expect("stops");
    assert!(
        dev.check_servo().is_err(),
        "the fault stays reported after stop()"
    );
    dev.close().expect("closes");

    // A callback that ignores the fault keeps running; the owner polls and stops it.
    let mut dev = open_hd(&fake);
    fake.set_int("set_fault_after_ticks", 5);
    dev.start(|_| HdCommand::Continue {
        force_n: [0.1, 0.0, 0.0],
    })
    .expect("starts");
    wait_for("the owner to see the fault", || dev.check_servo().is_err());
    assert!(dev.servo_status().running);
    let status = dev.stop().expect("stops");
    assert_eq!(status.first_error.map(|e| e.code), Some(0x0300));
    dev.close().expect("closes");
}

#[test]
fn hd_panicking_callback_stops_with_zero_force() {
    let _g = lock();
    let fake = fake_hd();
    let mut dev = open_hd(&fake);
    // Keep the deliberate panic's message and backtrace out of the test output.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let p = info.payload();
        let msg = p
            .downcast_ref::<&str>()
            .copied()
            .or_else(|| p.downcast_ref::<String>().map(String::as_str));
        if !msg.is_some_and(|m| m.starts_with("deliberate panic")) {
            default_hook(info);
        }
    }));
    dev.start(|s| {
        if s.tick == 3 {
            panic!("deliberate panic in a servo callback (test)");
        }
        HdCommand::Continue {
            force_n: [1.0, 0.0, 0.0],
        }
    })
    .expect("starts");
    wait_for("the servo to stop", || !dev.servo_status().running);
    drop(std::panic::take_hook());
    let status = dev.servo_status();
    assert!(status.callback_panicked && status.ticks == 3, "{status:?}");
    assert_eq!(
        fake.force_log(),
        vec![[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0; 3]]
    );
    assert_eq!(fake.calls("hdBeginFrame"), fake.calls("hdEndFrame"));
    assert_eq!(dev.check_servo(), Err(HapticsError::CallbackPanicked));
    dev.close().expect("closes");
}
