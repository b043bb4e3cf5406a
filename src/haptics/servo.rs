//! The servo loop: 1 kHz on its own thread for a pull device (absolute deadlines: sleep until
//! shortly before each, then spin), or inside a push device's scheduler. Each tick reads the
//! stylus, hands its state to the simulation through a [`StylusSlot`], reads the newest
//! [`HapticFrame`] without waiting, runs a [`ServoCore`] tick and writes the force. Every
//! period's error against the nominal period is kept for the timing figures.

use super::device::{
    DeviceState, Drive, HapticDevice, HapticsError, PullDevice, PushDevice, PushReply,
    ServoCallback,
};
use super::render::ServoCore;
use super::safety::SafetyParams;
use crate::sim::{Hand, HapticSlot, SeqWords, SimEvent};
use glam::DVec3;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Words in a stylus state: position and velocity (3 each) and the buttons.
const STYLUS_WORDS: usize = 7;

/// The stylus' newest state, written by the servo loop and read by the simulation: a
/// sequence lock ([`SeqWords`]) as [`HapticSlot`] is, so neither side ever waits on the other.
#[derive(Debug, Default)]
pub struct StylusSlot {
    words: SeqWords<STYLUS_WORDS>,
}

impl StylusSlot {
    pub fn new() -> StylusSlot {
        StylusSlot::default()
    }

    /// Publishes a state (one writer: the servo loop). Never waits.
    pub fn publish(&self, s: &DeviceState) {
        let p = s.position_m.to_array();
        let v = s.velocity_m_per_s.to_array();
        self.words.write([
            p[0].to_bits(),
            p[1].to_bits(),
            p[2].to_bits(),
            v[0].to_bits(),
            v[1].to_bits(),
            v[2].to_bits(),
            u64::from(s.buttons),
        ]);
    }

    /// The newest whole state; none before the first publish.
    pub fn latest(&self) -> Option<DeviceState> {
        self.words.read().map(|w| {
            let f = |i: usize| f64::from_bits(w[i]);
            DeviceState {
                position_m: DVec3::new(f(0), f(1), f(2)),
                velocity_m_per_s: DVec3::new(f(3), f(4), f(5)),
                buttons: w[6] as u32,
            }
        })
    }
}

/// How a servo loop runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoConfig {
    /// The instrument the device drives.
    pub hand: Hand,
    /// Field metres per device metre (see [`super::Workspace`]).
    pub workspace_scale: f64,
    pub safety: SafetyParams,
    /// The nominal servo period, s. Default 0.001 (1 kHz).
    pub period_s: f64,
    /// The loop sleeps until this long before each deadline, then spins, s. Default 0.0005:
    /// wide enough to take in the wake-up lateness of a sleeping thread on a loaded machine
    /// (its own core is left to it; see `stand::sim_pool`).
    pub spin_s: f64,
    /// How long it runs, s (it also stops when asked).
    pub duration_s: f64,
    /// Whether the device's clutch decouples it (no force while held; see
    /// [`super::clutch`]).
    pub clutch: bool,
}

impl Default for ServoConfig {
    fn default() -> Self {
        ServoConfig {
            hand: Hand::Right,
            workspace_scale: 1.0,
            safety: SafetyParams::default(),
            period_s: 0.001,
            spin_s: 0.0005,
            duration_s: 3.0,
            clutch: false,
        }
    }
}

/// What the servo loop shares with the rest of the program.
#[derive(Debug, Clone)]
pub struct ServoLinks {
    /// The simulation's haptic frames (read).
    pub frames: Arc<HapticSlot>,
    /// The stylus for the simulation (written).
    pub stylus: Arc<StylusSlot>,
    /// Set to end the loop early.
    pub stop: Arc<AtomicBool>,
    /// Set by the loop while forces are held off at start-up past the safety's notice time
    /// (the stylus keeps moving or is held in the tissue), so the owner can say why.
    pub held_off: Arc<AtomicBool>,
}

impl ServoLinks {
    /// Links to the simulation's haptic frames, with a new stylus slot and flags.
    pub fn new(frames: Arc<HapticSlot>, stop: Arc<AtomicBool>) -> ServoLinks {
        ServoLinks {
            frames,
            stylus: Arc::new(StylusSlot::new()),
            stop,
            held_off: Arc::new(AtomicBool::new(false)),
        }
    }
}

/// How a servo run went: the `haptics` command's figures.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ServoReport {
    /// Ticks per second of wall clock, first tick to last.
    pub rate_hz: f64,
    /// The median of |period - nominal period|, ms.
    pub period_p50_error_ms: f64,
    /// The 99th percentile of |period - nominal period|, ms.
    pub period_p99_error_ms: f64,
    /// The largest force written, N.
    pub max_force_n: f64,
    /// Clamp events (runs of ticks whose force or stiffness was limited).
    pub clamps: u64,
    /// Stalls of the simulation (no frame for 10 ms).
    pub stalls: u64,
    pub ticks: u64,
    pub clamped_ticks: u64,
    /// Non-finite events.
    pub non_finite: u64,
    /// Deadlines passed over after a hiccup, so the loop kept its 1 kHz grid without a burst.
    pub skipped_deadlines: u64,
    /// The device's force limit, N.
    pub limit_force_n: f64,
    /// The events the safety raised (for the session's stream).
    #[serde(skip)]
    pub events: Vec<SimEvent>,
}

/// Every period's length, for the timing figures.
#[derive(Debug, Clone)]
struct PeriodLog {
    period_s: f64,
    start: Option<Instant>,
    prev: Option<Instant>,
    last: Option<Instant>,
    errors_s: Vec<f64>,
    ticks: u64,
}

impl PeriodLog {
    fn new(period_s: f64, duration_s: f64) -> PeriodLog {
        // Room for the whole run up front: no allocation in the loop (up to ~3 h).
        let expected = (duration_s / period_s).clamp(0.0, 1e7) as usize;
        PeriodLog {
            period_s,
            start: None,
            prev: None,
            last: None,
            errors_s: Vec::with_capacity(expected + 1024),
            ticks: 0,
        }
    }

    /// A tick at `now`: the time since the previous one, s (0 for the first).
    fn tick(&mut self, now: Instant) -> f64 {
        self.start.get_or_insert(now);
        self.ticks += 1;
        self.last = Some(now);
        let dt = self
            .prev
            .replace(now)
            .map_or(0.0, |p| now.duration_since(p).as_secs_f64());
        if self.ticks > 1 {
            self.errors_s.push((dt - self.period_s).abs());
        }
        dt
    }

    /// Seconds since the first tick.
    fn since_start(&self, now: Instant) -> f64 {
        self.start
            .map_or(0.0, |s| now.duration_since(s).as_secs_f64())
    }

    fn into_report(mut self, core: &mut ServoCore, skipped: u64) -> ServoReport {
        self.errors_s.sort_by(f64::total_cmp);
        let pct = |q: f64| -> f64 {
            let n = self.errors_s.len();
            if n == 0 {
                return 0.0;
            }
            let rank = ((q * n as f64).ceil() as usize).clamp(1, n);
            self.errors_s[rank - 1] * 1e3
        };
        let span = match (self.start, self.last) {
            (Some(a), Some(b)) => b.duration_since(a).as_secs_f64(),
            _ => 0.0,
        };
        let c = core.counters();
        ServoReport {
            rate_hz: if span > 0.0 {
                (self.ticks - 1) as f64 / span
            } else {
                0.0
            },
            period_p50_error_ms: pct(0.5),
            period_p99_error_ms: pct(0.99),
            max_force_n: core.max_force_n(),
            clamps: c.clamps,
            stalls: c.stalls,
            ticks: c.ticks,
            clamped_ticks: c.clamped_ticks,
            non_finite: c.non_finite,
            skipped_deadlines: skipped,
            limit_force_n: core.limits().max_force_n,
            events: core.take_events(),
        }
    }
}

/// The line said once for a device whose forces are held off at start-up (see
/// [`ServoLinks::held_off`]).
pub fn held_off_notice(device: &str, hand: Hand) -> String {
    format!(
        "{device} on the {} hand: forces stay off until the stylus is held still, out of the \
         tissue, for a moment (then they ramp up over 2 s)",
        hand.name()
    )
}

/// Waits until `deadline`: sleeps until `spin` before it, then spins.
fn wait_until(deadline: Instant, spin: Duration) {
    let now = Instant::now();
    if let Some(sleep) = deadline.checked_duration_since(now + spin) {
        std::thread::sleep(sleep);
    }
    while Instant::now() < deadline {
        std::hint::spin_loop();
    }
}

/// Runs the servo loop on `device` until `config.duration_s` has passed or `links.stop` is
/// set; call it on the thread that is to be the servo thread (a push device's scheduler has
/// its own). The force is zero when it returns, whichever way.
pub fn run_servo(
    device: &mut dyn HapticDevice,
    links: &ServoLinks,
    config: &ServoConfig,
) -> Result<ServoReport, HapticsError> {
    let mut core = ServoCore::new(
        device.limits(),
        config.hand,
        config.workspace_scale,
        config.safety,
    );
    if config.clutch {
        core = core.with_clutch(device.kind());
    }
    let name = device.name().to_string();
    match device.drive() {
        Drive::Pull(d) => run_pull(d, core, links, config),
        Drive::Push(d) => run_push(d, &name, core, links, config),
    }
}

fn run_pull(
    device: &mut dyn PullDevice,
    mut core: ServoCore,
    links: &ServoLinks,
    config: &ServoConfig,
) -> Result<ServoReport, HapticsError> {
    let period = Duration::from_secs_f64(config.period_s.max(1e-5));
    let spin = Duration::from_secs_f64(config.spin_s.clamp(0.0, config.period_s));
    let mut log = PeriodLog::new(config.period_s, config.duration_s);
    let mut skipped = 0;
    let mut next = Instant::now();
    let result = loop {
        wait_until(next, spin);
        let _tick = tracing::trace_span!("servo_tick").entered();
        let now = Instant::now();
        // A tick far later than one period (the thread was preempted) moves no further
        // than the longest substep sequence the simulated stylus takes in stride.
        let dt = log.tick(now);
        device.advance(dt.min(0.05));
        let state = match device.read() {
            Ok(s) => s,
            Err(e) => break Err(e),
        };
        links.stylus.publish(&state);
        let frame = links.frames.latest();
        let force = core.tick(log.since_start(now), &state, &frame);
        links.held_off.store(core.held_off(), Ordering::Relaxed);
        if let Err(e) = device.write_force(force) {
            break Err(e);
        }
        if links.stop.load(Ordering::Relaxed) || log.since_start(now) >= config.duration_s {
            break Ok(());
        }
        // Absolute deadlines on a fixed grid; after a hiccup of several periods, the missed
        // deadlines are passed over instead of run in a burst.
        next += period;
        let now = Instant::now();
        if now > next + 2 * period {
            let behind = now.duration_since(next).as_secs_f64() / period.as_secs_f64();
            let k = behind.ceil() as u32;
            skipped += u64::from(k);
            next += period * k;
        }
    };
    let zeroed = device.write_force(DVec3::ZERO);
    result?;
    zeroed?;
    Ok(log.into_report(&mut core, skipped))
}

fn run_push(
    device: &mut dyn PushDevice,
    name: &str,
    mut core: ServoCore,
    links: &ServoLinks,
    config: &ServoConfig,
) -> Result<ServoReport, HapticsError> {
    let (tx, rx) = std::sync::mpsc::channel();
    let mut log = PeriodLog::new(config.period_s, config.duration_s);
    let links = links.clone();
    let duration_s = config.duration_s;
    let mut done = false;
    let servo: ServoCallback = Box::new(move |state: &DeviceState| {
        let _tick = tracing::trace_span!("servo_tick").entered();
        if done {
            return PushReply {
                force_n: DVec3::ZERO,
                go_on: false,
            };
        }
        let now = Instant::now();
        log.tick(now);
        links.stylus.publish(state);
        let frame = links.frames.latest();
        let force = core.tick(log.since_start(now), state, &frame);
        links.held_off.store(core.held_off(), Ordering::Relaxed);
        done = links.stop.load(Ordering::Relaxed) || log.since_start(now) >= duration_s;
        if done {
            let report = std::mem::replace(&mut log, PeriodLog::new(1.0, 0.0));
            // The receiver waits for this; if it is gone there is no one to tell.
            let _ = tx.send(report.into_report(&mut core, 0));
        }
        PushReply {
            force_n: if done { DVec3::ZERO } else { force },
            go_on: !done,
        }
    });
    device.run(servo)?;
    rx.try_recv().map_err(|_| HapticsError::Drive {
        device: name.to_string(),
        message: "its scheduler stopped before the servo loop was done",
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::haptics::device::{DeviceKind, DeviceLimits};
    use crate::haptics::simulated::{Script, SimulatedStylus, StylusParams};
    use crate::sim::{HapticFrame, ToolHaptics};
    use glam::Vec3;

    fn links() -> ServoLinks {
        ServoLinks::new(
            Arc::new(HapticSlot::new()),
            Arc::new(AtomicBool::new(false)),
        )
    }

    #[test]
    fn the_stylus_slot_reads_back_whole() {
        let slot = StylusSlot::new();
        assert_eq!(slot.latest(), None);
        let s = DeviceState {
            position_m: DVec3::new(0.1, -0.2, 0.3),
            velocity_m_per_s: DVec3::new(-1.0, 2.0, f64::INFINITY),
            buttons: 5,
        };
        slot.publish(&s);
        assert_eq!(slot.latest(), Some(s));
    }

    /// A push device whose "scheduler" is a loop on the caller's thread.
    struct FakeScheduler {
        calls: u64,
        forces: Vec<DVec3>,
    }

    impl PushDevice for FakeScheduler {
        fn run(&mut self, mut servo: ServoCallback) -> Result<(), HapticsError> {
            let state = DeviceState::default();
            loop {
                self.calls += 1;
                let r = servo(&state);
                self.forces.push(r.force_n);
                if !r.go_on || self.calls > 100_000 {
                    return Ok(());
                }
                std::thread::sleep(Duration::from_micros(500));
            }
        }
    }

    impl HapticDevice for FakeScheduler {
        fn name(&self) -> &str {
            "fake scheduler"
        }
        fn kind(&self) -> DeviceKind {
            DeviceKind::PhantomOmni
        }
        fn limits(&self) -> DeviceLimits {
            DeviceKind::PhantomOmni.table_limits()
        }
        fn drive(&mut self) -> Drive<'_> {
            Drive::Push(self)
        }
    }

    #[test]
    fn a_push_device_runs_the_servo_in_its_scheduler_and_stops_on_time() {
        let l = links();
        let mut dev = FakeScheduler {
            calls: 0,
            forces: Vec::new(),
        };
        let config = ServoConfig {
            duration_s: 0.05,
            ..ServoConfig::default()
        };
        let report = run_servo(&mut dev, &l, &config).expect("runs");
        // It stopped when told (not after the fake's 100000 calls), with zero force last.
        assert!(dev.calls < 100_000);
        assert_eq!(report.ticks, dev.calls);
        assert_eq!(dev.forces.last(), Some(&DVec3::ZERO));
        assert!(l.stylus.latest().is_some());
        assert_eq!(report.limit_force_n, 3.3);
        // It ran; no frame came, so there was no force.
        assert!(report.ticks > 1 && report.max_force_n == 0.0);
    }

    #[test]
    fn a_pull_device_runs_on_this_thread_and_feels_the_frames() {
        let l = links();
        // A frame that pushes up with 1 N (more than the 0.25 N start-up threshold: it must
        // wait for the stylus to be still with a small force, so the frame comes later).
        let mut dev = SimulatedStylus::new(Script::hold(DVec3::ZERO), StylusParams::default());
        // A second of ticks: on a loaded machine the publisher's 1 ms sleeps stretch, and a
        // late frame stalls the watchdog, whose gain takes 0.25 s to come back.
        let config = ServoConfig {
            duration_s: 1.0,
            safety: SafetyParams {
                ramp_up_s: 0.05,
                ..SafetyParams::default()
            },
            ..ServoConfig::default()
        };
        let frames = l.frames.clone();
        let stop = l.stop.clone();
        let report = std::thread::scope(|s| {
            s.spawn(|| {
                let mut tool = ToolHaptics::default();
                let mut step = 0;
                let start = std::time::Instant::now();
                while !stop.load(Ordering::Relaxed) {
                    // The force comes after 0.2 s by the wall clock, however many frames.
                    if start.elapsed() > Duration::from_millis(200) {
                        tool = ToolHaptics {
                            force_n: Vec3::new(0.0, 1.0, 0.0),
                            normal: Vec3::Y,
                            in_contact: true,
                            ..ToolHaptics::default()
                        };
                    }
                    frames.publish(&HapticFrame {
                        step,
                        time_s: (step + 1) as f64 * 0.001,
                        tools: [ToolHaptics::default(), tool],
                    });
                    step += 1;
                    std::thread::sleep(Duration::from_millis(1));
                }
            });
            let r = run_servo(&mut dev, &l, &config);
            stop.store(true, Ordering::Relaxed);
            r
        })
        .expect("runs");
        // Behaviour, not timing: it ticked, felt the frame's force, and clamps nothing.
        assert!(report.ticks > 10);
        assert!(report.max_force_n > 0.0 && report.max_force_n <= 1.0 + 1e-9);
        assert_eq!(report.clamps, 0);
        assert!(report.rate_hz > 0.0 && report.period_p99_error_ms >= report.period_p50_error_ms);
        // The stylus was pushed up off its hand.
        assert!(dev.position_m().y > 0.0);
    }
}
