//! The one place a device named on the command line is opened, and the adapters that make the
//! vendor drivers of `xr-bindings` devices of the servo loop: OpenHaptics HD (Phantom Omni,
//! Touch) is a *push* device, its scheduler calling our servo; Force Dimension DHD (Novint
//! Falcon, omega) is a *pull* device, read and written by our own 1 kHz thread.
//!
//! Both libraries are opened at run time: without them, asking for the device is a clear
//! error that names the library, the vendor and the variable that points to it.

use std::path::Path;
use std::time::{Duration, Instant};

use glam::DVec3;
use xr_bindings::haptics::{self as vendor, DhdDevice, HdCommand, HdDevice, HdState};

use super::device::{
    DeviceKind, DeviceLimits, DeviceState, Drive, HapticDevice, HapticsError, PullDevice,
    PushDevice, PushReply, ServoCallback,
};
use super::simulated::{Script, SimulatedStylus, StylusParams};

/// A device the command line can ask for (named in the core: a procedure says its own).
pub use crate::sim::DeviceChoice;

/// Opens the device `choice` names; a Phantom by its HD device name (`None`: HD's default
/// device).
pub fn open_device(
    choice: DeviceChoice,
    hd_name: Option<&str>,
) -> Result<Box<dyn HapticDevice>, HapticsError> {
    let flag = choice.flag();
    let vendor_error = |source| HapticsError::Vendor { flag, source };
    Ok(match choice {
        DeviceChoice::Sim => Box::new(SimulatedStylus::new(
            Script::press(),
            StylusParams::default(),
        )),
        DeviceChoice::Phantom => Box::new(HdStylus::open(hd_name).map_err(vendor_error)?),
        DeviceChoice::Falcon => Box::new(DhdStylus::open().map_err(vendor_error)?),
    })
}

/// A vendor error on an open device, named for people.
fn device_fault(device: &str, source: vendor::HapticsError) -> HapticsError {
    HapticsError::Device {
        device: device.to_string(),
        message: source.to_string(),
    }
}

/// How often the owner of an HD servo looks for its end or a device fault.
const HD_POLL: Duration = Duration::from_millis(2);

/// A Phantom Omni or Touch: HD's scheduler calls the servo at 1 kHz on its own thread.
pub struct HdStylus {
    device: HdDevice,
    name: String,
    limits: DeviceLimits,
}

impl HdStylus {
    /// Opens the HD device `name` (`None`: the default device).
    pub fn open(name: Option<&str>) -> Result<HdStylus, vendor::HapticsError> {
        Self::open_with(None, name)
    }

    /// Like [`HdStylus::open`] with HD loaded from `library` when given (no search).
    pub fn open_with(
        library: Option<&Path>,
        name: Option<&str>,
    ) -> Result<HdStylus, vendor::HapticsError> {
        let device = match library {
            Some(l) => HdDevice::open_from(l, name)?,
            None => HdDevice::open(name)?,
        };
        // The Omni's table (the Touch's stiffness is lower, and a Touch reports it): the
        // lesser of the device's nominal figures and the table's holds.
        let limits = DeviceLimits::for_device(
            DeviceKind::PhantomOmni,
            Some(device.nominal_max_force_n()),
            Some(device.nominal_max_stiffness_n_per_m()),
        );
        let name = format!(
            "Phantom Omni / Touch '{}'",
            name.unwrap_or("default device")
        );
        Ok(HdStylus {
            device,
            name,
            limits,
        })
    }
}

/// HD's state as the servo sees it.
fn hd_state(s: &HdState) -> DeviceState {
    DeviceState {
        position_m: DVec3::from_array(s.position_m),
        velocity_m_per_s: DVec3::from_array(s.velocity_m_per_s),
        buttons: s.buttons,
    }
}

impl HapticDevice for HdStylus {
    fn name(&self) -> &str {
        &self.name
    }
    fn kind(&self) -> DeviceKind {
        DeviceKind::PhantomOmni
    }
    fn limits(&self) -> DeviceLimits {
        self.limits
    }
    fn drive(&mut self) -> Drive<'_> {
        Drive::Push(self)
    }
}

impl PushDevice for HdStylus {
    fn run(&mut self, mut servo: ServoCallback) -> Result<(), HapticsError> {
        let fault = |e| device_fault(&self.name, e);
        self.device.enable_force_output().map_err(fault)?;
        self.device
            .start(move |s: &HdState| {
                // A device fault ends the servo with zero force; the owner reports it.
                if s.error.is_some() {
                    return HdCommand::Stop;
                }
                let reply: PushReply = servo(&hd_state(s));
                if reply.go_on {
                    HdCommand::Continue {
                        force_n: reply.force_n.to_array(),
                    }
                } else {
                    HdCommand::Stop
                }
            })
            .map_err(fault)?;
        // Wait for the servo to say it is done, or for the device to fault.
        let outcome = loop {
            std::thread::sleep(HD_POLL);
            if let Err(e) = self.device.check_servo() {
                break Err(e);
            }
            if !self.device.servo_status().running {
                break Ok(());
            }
        };
        let stopped = self.device.stop();
        let disabled = self.device.disable_force_output();
        outcome.map_err(fault)?;
        stopped.map_err(fault)?;
        disabled.map_err(fault)?;
        Ok(())
    }
}

/// DHD's watchdog: the device cuts its forces when no force command came for this long, so a
/// stalled or killed servo thread leaves the user's hand free within ten periods.
pub const DHD_WATCHDOG: Duration = Duration::from_millis(10);

/// Time constant of the velocity estimate from successive positions, s: a few servo periods,
/// enough to smooth the encoders' quantisation without lagging a hand's motion.
const VELOCITY_TAU_S: f64 = 0.005;

/// A velocity from successive positions (DHD reports none to the calls we use): the finite
/// difference over the time between reads, smoothed with [`VELOCITY_TAU_S`].
#[derive(Debug, Clone, Copy, Default)]
struct VelocityEstimate {
    last: Option<(DVec3, Instant)>,
    velocity: DVec3,
}

impl VelocityEstimate {
    fn update(&mut self, position: DVec3, now: Instant) -> DVec3 {
        if let Some((before, then)) = self.last {
            let dt = now.saturating_duration_since(then).as_secs_f64();
            if dt > 0.0 {
                let raw = (position - before) / dt;
                self.velocity += (raw - self.velocity) * (dt / (VELOCITY_TAU_S + dt));
            }
        }
        self.last = Some((position, now));
        self.velocity
    }
}

/// A Novint Falcon or omega: our servo thread reads and writes it each tick.
pub struct DhdStylus {
    device: DhdDevice,
    name: String,
    kind: DeviceKind,
    limits: DeviceLimits,
    velocity: VelocityEstimate,
    /// Force commands the device clipped at a motor's limit.
    pub saturated: u64,
}

impl DhdStylus {
    /// Opens the first Force Dimension device, caps its forces at the lesser of its own limit
    /// and the table's (in the SDK too), arms its watchdog and turns its forces on.
    pub fn open() -> Result<DhdStylus, vendor::HapticsError> {
        Self::open_with(None)
    }

    /// Like [`DhdStylus::open`] with DHD loaded from `library` when given (no search).
    pub fn open_with(library: Option<&Path>) -> Result<DhdStylus, vendor::HapticsError> {
        let mut device = match library {
            Some(l) => DhdDevice::open_from(l)?,
            None => DhdDevice::open()?,
        };
        let kind = match device.system_type()? {
            vendor::DHD_DEVICE_OMEGA3
            | vendor::DHD_DEVICE_OMEGA33
            | vendor::DHD_DEVICE_OMEGA331 => DeviceKind::Omega3,
            // The Falcon, and any other model: the Falcon's figures are the smallest of the
            // DHD devices in the table, so they are safe on all of them.
            _ => DeviceKind::Falcon,
        };
        let reported = match device.max_force_n() {
            Ok(f) => f,
            // An SDK too old to report it: the table holds.
            Err(vendor::HapticsError::MissingSymbol { .. }) => None,
            Err(e) => return Err(e),
        };
        let limits = DeviceLimits::for_device(kind, reported, None);
        match device.set_max_force_n(Some(limits.max_force_n)) {
            Ok(()) | Err(vendor::HapticsError::MissingSymbol { .. }) => {}
            Err(e) => return Err(e),
        }
        device.set_watchdog(DHD_WATCHDOG)?;
        device.enable_force(true)?;
        let name = format!(
            "{} (DHD device {})",
            device
                .system_name()
                .unwrap_or_else(|_| kind.name().to_string()),
            device.id()
        );
        Ok(DhdStylus {
            device,
            name,
            kind,
            limits,
            velocity: VelocityEstimate::default(),
            saturated: 0,
        })
    }
}

impl HapticDevice for DhdStylus {
    fn name(&self) -> &str {
        &self.name
    }
    fn kind(&self) -> DeviceKind {
        self.kind
    }
    fn limits(&self) -> DeviceLimits {
        self.limits
    }
    fn drive(&mut self) -> Drive<'_> {
        Drive::Pull(self)
    }
}

impl PullDevice for DhdStylus {
    fn read(&mut self) -> Result<DeviceState, HapticsError> {
        let position = DVec3::from_array(
            self.device
                .position_m()
                .map_err(|e| device_fault(&self.name, e))?,
        );
        let velocity = self.velocity.update(position, Instant::now());
        Ok(DeviceState {
            position_m: position,
            velocity_m_per_s: velocity,
            buttons: self.device.buttons(),
        })
    }

    fn write_force(&mut self, force_n: DVec3) -> Result<(), HapticsError> {
        let status = self
            .device
            .set_force_n(force_n.to_array())
            .map_err(|e| device_fault(&self.name, e))?;
        self.saturated += u64::from(status.saturated);
        Ok(())
    }
}

impl Drop for DhdStylus {
    fn drop(&mut self) {
        // Forces off before the device closes (dropping DhdDevice closes it); nothing to do
        // about an error on the way out.
        let _ = self.device.set_force_n([0.0; 3]);
        let _ = self.device.enable_force(false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simulated_stylus_has_the_omni_limits() {
        let sim = open_device(DeviceChoice::Sim, None).map(|d| d.limits().max_force_n);
        assert_eq!(sim.ok(), Some(3.3));
    }

    /// A stylus moving at 0.1 m/s, read every millisecond: the estimate settles on 0.1 m/s
    /// (within 1% after 10 time constants), and a stop brings it back to zero.
    #[test]
    fn the_velocity_estimate_follows_a_steady_motion_and_a_stop() {
        let mut e = VelocityEstimate::default();
        let t0 = Instant::now();
        let v = DVec3::new(0.1, -0.05, 0.0);
        let mut got = DVec3::ZERO;
        let n = (10.0 * VELOCITY_TAU_S / 1e-3) as u32;
        for k in 0..=n {
            let t = f64::from(k) * 1e-3;
            got = e.update(v * t, t0 + Duration::from_secs_f64(t));
        }
        assert!((got - v).length() < 0.01 * v.length(), "{got}");
        let stop = v * f64::from(n) * 1e-3;
        for k in 1..=n {
            let t = f64::from(n + k) * 1e-3;
            got = e.update(stop, t0 + Duration::from_secs_f64(t));
        }
        assert!(got.length() < 0.01 * v.length(), "{got}");
    }
}
