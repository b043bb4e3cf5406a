//! An injected session loss, through the Khronos loader: the runtime reports LOSS_PENDING at
//! the configured display time, the app destroys the session, polls until the headset is back,
//! creates a new session and runs on to a clean exit; the runtime's state log keeps both.

mod common;

use openxr as xr;
use xr_bindings::{Command, SessionMachine};

#[test]
fn a_lost_session_is_recreated_and_the_state_log_keeps_both() {
    let dir = common::temp_dir("loss");
    let config = format!(
        "out_dir = \"{}\"\n[inject]\nsession_loss_s = 0.5\nheadset_back_after_polls = 3\n",
        dir.display()
    );
    common::use_runtime(&dir, Some(&config));
    let rig = common::Rig::open();
    let instance = &rig.instance;
    let mut live = Some(rig.session().expect("session"));
    let mut machine = SessionMachine::new();
    let mut buf = xr::EventDataBuffer::new();
    let mut frames_after_restart = 0;
    let mut asked_to_exit = false;
    let mut unavailable = 0;
    let mut loss_time = None;
    'run: for _ in 0..2000 {
        while let Some(event) = instance.poll_event(&mut buf).expect("poll") {
            let xr::Event::SessionStateChanged(e) = event else {
                continue;
            };
            let Some((session, _, _)) = live.as_ref() else {
                continue;
            };
            match common::obey(machine.on_state(e.state()), session) {
                Some(Command::Exit) => break 'run,
                Some(Command::Recreate) => {
                    loss_time = Some(e.time().as_nanos());
                    // Destroy the session, then wait for the headset to come back.
                    drop(live.take());
                    loop {
                        match instance.system(xr::FormFactor::HEAD_MOUNTED_DISPLAY) {
                            Ok(_) => break,
                            Err(xr::sys::Result::ERROR_FORM_FACTOR_UNAVAILABLE) => {
                                unavailable += 1;
                                assert!(unavailable < 100, "the headset never came back");
                            }
                            Err(other) => panic!("xrGetSystem: {other}"),
                        }
                    }
                    live = Some(rig.session().expect("a new session"));
                    machine.recreated();
                    break;
                }
                _ => {}
            }
        }
        let Some((session, waiter, stream)) = live.as_mut() else {
            continue;
        };
        if machine.submits_frames() {
            let frame = common::frame(waiter, stream, |_| {});
            if machine.restarts == 1 && frame.should_render {
                frames_after_restart += 1;
            }
        }
        if machine.focused() && frames_after_restart >= 30 && !asked_to_exit {
            session.request_exit().expect("request exit");
            asked_to_exit = true;
        }
    }
    assert_eq!(machine.restarts, 1);
    assert_eq!(unavailable, 3, "the headset stays away for 3 polls");
    // The loss came at the first frame at or after 0.5 s: 46 periods of 11.1 ms after the
    // first frame (45 periods fall 5 ns short).
    let first = 1_000_000_000i64;
    let period = vesalius_sim_runtime::FRAME_PERIOD_NS;
    assert_eq!(loss_time, Some(first + 46 * period));
    assert!(machine.unexpected.is_empty(), "{:?}", machine.unexpected);
    assert_eq!(machine.history.last(), Some(&xr::SessionState::EXITING));
    drop(live);
    // The runtime's log, written when the session was destroyed: both sessions, in order.
    let log = std::fs::read_to_string(dir.join("session-states.log")).expect("state log");
    let lines: Vec<&str> = log.lines().collect();
    assert!(
        lines.iter().any(|l| l.ends_with(" 1 LOSS_PENDING")),
        "{log}"
    );
    assert!(lines.iter().any(|l| l.ends_with(" 2 FOCUSED")), "{log}");
    assert_eq!(
        lines.last().map(|l| l.ends_with(" 2 EXITING")),
        Some(true),
        "{log}"
    );
    let times: Vec<i64> = lines
        .iter()
        .filter_map(|l| l.split(' ').next()?.parse().ok())
        .collect();
    assert!(
        times.windows(2).all(|w| w[0] <= w[1]),
        "time runs forward: {log}"
    );
}
