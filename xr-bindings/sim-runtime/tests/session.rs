//! A Vulkan session through the Khronos loader: the app's Vulkan instance and device are made
//! through the simulated runtime (XR_KHR_vulkan_enable2, on whatever Vulkan driver is
//! installed: lavapipe in CI), and the session walks IDLE -> READY -> SYNCHRONIZED -> VISIBLE
//! -> FOCUSED -> ... -> STOPPING -> IDLE -> EXITING under the app's state machine.

mod common;

use openxr as xr;
use xr_bindings::{Command, SessionMachine};

#[test]
fn a_vulkan_session_walks_the_whole_life_cycle() {
    let dir = common::temp_dir("session");
    common::use_runtime(&dir, None);
    let rig = common::Rig::open();
    let instance = &rig.instance;
    let (session, mut waiter, mut stream) = rig.session().expect("session");
    let stage = session
        .create_reference_space(xr::ReferenceSpaceType::STAGE, xr::Posef::IDENTITY)
        .expect("stage space");

    let mut machine = SessionMachine::new();
    let mut buf = xr::EventDataBuffer::new();
    let mut asked_to_exit = false;
    let mut times = Vec::new();
    let mut rendered = 0;
    'run: for _ in 0..1000 {
        while let Some(event) = instance.poll_event(&mut buf).expect("poll") {
            let xr::Event::SessionStateChanged(e) = event else {
                continue;
            };
            match common::obey(machine.on_state(e.state()), &session) {
                Some(Command::Exit) => break 'run,
                Some(Command::Recreate) => panic!("no loss was injected"),
                _ => {}
            }
        }
        if machine.submits_frames() {
            let frame = common::frame(&mut waiter, &mut stream, |frame| {
                if !frame.should_render {
                    return;
                }
                let (_, views) = session
                    .locate_views(
                        xr::ViewConfigurationType::PRIMARY_STEREO,
                        frame.predicted_display_time,
                        &stage,
                    )
                    .expect("views");
                assert_eq!(views.len(), 2);
                let (l, r) = (views[0].pose.position, views[1].pose.position);
                let (dx, dy, dz) = (r.x - l.x, r.y - l.y, r.z - l.z);
                let ipd = (dx * dx + dy * dy + dz * dz).sqrt();
                assert!((ipd - 0.063).abs() < 1e-5, "IPD {ipd}");
                // The default head: eyes 1.6 m above the floor, right eye to the right.
                assert!(((l.y + r.y) / 2.0 - 1.6).abs() < 1e-5);
                assert!(dx > 0.06);
                assert_eq!(views[0].fov.angle_left, -views[1].fov.angle_right);
            });
            times.push(frame.predicted_display_time.as_nanos());
            rendered += usize::from(frame.should_render);
        }
        if machine.focused() && rendered >= 120 && !asked_to_exit {
            // The trainee is done: ask the runtime to wind the session down.
            session.request_exit().expect("request exit");
            asked_to_exit = true;
        }
    }
    // A 90 Hz display: every predicted time one period after the last.
    assert!(times.len() > 120, "{} frames", times.len());
    assert!(
        times.windows(2).all(|w| w[1] - w[0] == 1_000_000_000 / 90),
        "display times step by 11.1 ms"
    );
    use xr::SessionState as S;
    assert_eq!(
        machine.history,
        [
            S::IDLE,
            S::READY,
            S::SYNCHRONIZED,
            S::VISIBLE,
            S::FOCUSED,
            S::VISIBLE,
            S::SYNCHRONIZED,
            S::STOPPING,
            S::IDLE,
            S::EXITING
        ]
    );
    assert!(machine.unexpected.is_empty(), "{:?}", machine.unexpected);
    // Ending twice is refused with the OpenXR error, not a crash.
    assert_eq!(
        session.end(),
        Err(xr::sys::Result::ERROR_SESSION_NOT_RUNNING)
    );
    drop(stage);
    drop(session);
    drop(waiter);
    drop(stream);
}
