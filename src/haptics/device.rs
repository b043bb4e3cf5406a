//! The device seam: what every force-feedback device is to the servo loop (its name, kind and
//! limits), and the two ways its servo ticks are driven. A *pull* device (Force Dimension DHD,
//! the simulated stylus) is read and written by our own 1 kHz thread; a *push* device
//! (OpenHaptics HD) has a vendor scheduler that calls our servo callback at its rate.

use glam::DVec3;

/// The devices Vesalius knows, for their nominal limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceKind {
    /// The simulated stylus (`--device sim`): given a Phantom Omni's limits, the papers'
    /// most common device, so what passes on it passes on the real one.
    Simulated,
    /// 3D Systems Phantom Omni (OpenHaptics HD).
    PhantomOmni,
    /// 3D Systems / Geomagic Touch (OpenHaptics HD).
    Touch,
    /// Novint Falcon (Force Dimension DHD).
    Falcon,
    /// Force Dimension omega.3 (DHD).
    Omega3,
}

impl DeviceKind {
    /// The nominal figures of `shared/HAPTICS.md` (CHAI3D's device tables): nothing is ever
    /// sent above them, whatever a device reports.
    pub fn table_limits(self) -> DeviceLimits {
        let (max_force_n, max_stiffness_n_per_m) = match self {
            DeviceKind::Simulated | DeviceKind::PhantomOmni => (3.3, 700.0),
            DeviceKind::Touch => (3.3, 400.0),
            // The table says 8 N (the catheter paper runs it at 9 N): the lesser holds.
            DeviceKind::Falcon => (8.0, 3000.0),
            DeviceKind::Omega3 => (12.0, 5000.0),
        };
        DeviceLimits {
            max_force_n,
            max_stiffness_n_per_m,
        }
    }

    /// Its name for people.
    pub fn name(self) -> &'static str {
        match self {
            DeviceKind::Simulated => "simulated stylus",
            DeviceKind::PhantomOmni => "Phantom Omni",
            DeviceKind::Touch => "Touch",
            DeviceKind::Falcon => "Novint Falcon",
            DeviceKind::Omega3 => "omega.3",
        }
    }
}

/// The most a device may be asked for. Positive and finite by construction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceLimits {
    /// Largest force magnitude sent to the device, N.
    pub max_force_n: f64,
    /// Stiffest spring rendered on it, N/m of stylus motion.
    pub max_stiffness_n_per_m: f64,
}

impl DeviceLimits {
    /// The limits a `kind` of device runs under: the lesser of what the device reports
    /// (`reported_*`, `None` where it reports nothing) and the table's figure, never above the
    /// table. A report that is not positive and finite (DHD reports a negative force for "no
    /// limit") is ignored.
    pub fn for_device(
        kind: DeviceKind,
        reported_force_n: Option<f64>,
        reported_stiffness_n_per_m: Option<f64>,
    ) -> DeviceLimits {
        let table = kind.table_limits();
        let lesser = |reported: Option<f64>, table: f64| match reported {
            Some(r) if r.is_finite() && r > 0.0 => r.min(table),
            _ => table,
        };
        DeviceLimits {
            max_force_n: lesser(reported_force_n, table.max_force_n),
            max_stiffness_n_per_m: lesser(reported_stiffness_n_per_m, table.max_stiffness_n_per_m),
        }
    }
}

/// What a device says at one servo tick, in SI units and the device's frame (x right, y up,
/// z toward the user, as HD and DHD both have it; an adapter converts HD's millimetres).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeviceState {
    /// Stylus tip position, m.
    pub position_m: DVec3,
    /// Stylus tip velocity, m/s.
    pub velocity_m_per_s: DVec3,
    /// Buttons held, a bit each (bit 0: the stylus' first button).
    pub buttons: u32,
}

impl DeviceState {
    pub fn is_finite(&self) -> bool {
        self.position_m.is_finite() && self.velocity_m_per_s.is_finite()
    }
}

/// Why a device cannot be used, or failed.
#[derive(Debug, thiserror::Error)]
pub enum HapticsError {
    /// The device named on the command line could not be opened: its vendor library is
    /// missing, no device answered, or the device refused a setting.
    #[error("--device {flag}: {source}")]
    Vendor {
        /// The command-line name (`phantom`, `falcon`).
        flag: &'static str,
        source: xr_bindings::haptics::HapticsError,
    },
    /// The device reported an error (a fault mid-session, a failed write).
    #[error("{device}: {message}")]
    Device { device: String, message: String },
    /// The device does not drive its servo ticks the way it was asked to.
    #[error("{device}: {message}")]
    Drive {
        device: String,
        message: &'static str,
    },
    /// The procedure for the servo loop could not be set up.
    #[error(transparent)]
    Session(#[from] Box<crate::session::SessionError>),
    /// A thread of the servo loop or its simulation failed.
    #[error("{0}")]
    Thread(String),
}

/// A force-feedback device as the servo loop sees it.
pub trait HapticDevice: Send {
    /// A name for people ("simulated stylus", "Phantom Omni 'Default PHANToM'").
    fn name(&self) -> &str;
    fn kind(&self) -> DeviceKind;
    /// Its limits: the lesser of what it reports and the table (see
    /// [`DeviceLimits::for_device`]).
    fn limits(&self) -> DeviceLimits;
    /// How its servo ticks are driven.
    fn drive(&mut self) -> Drive<'_>;
}

/// The two ways a device's servo ticks happen.
pub enum Drive<'a> {
    /// Our own 1 kHz thread reads and writes it (DHD, the simulated stylus).
    Pull(&'a mut dyn PullDevice),
    /// Its vendor's scheduler calls our servo callback (OpenHaptics HD).
    Push(&'a mut dyn PushDevice),
}

/// A device our servo thread reads and writes each tick.
pub trait PullDevice: Send {
    /// The stylus now.
    fn read(&mut self) -> Result<DeviceState, HapticsError>;
    /// The force to render until the next tick, N (already safe: finite, clamped).
    fn write_force(&mut self, force_n: DVec3) -> Result<(), HapticsError>;
    /// `dt_s` passed since the last tick. A device with its own physics (the simulated
    /// stylus) advances by it; a real device lets the world do that (the default).
    fn advance(&mut self, dt_s: f64) {
        let _ = dt_s;
    }
}

/// What a push device's servo callback answers each tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PushReply {
    /// The force to render, N (already safe).
    pub force_n: DVec3,
    /// False: this was the last tick; the device stops calling and renders no force.
    pub go_on: bool,
}

/// The servo callback a push device's scheduler calls: owned, since the vendor's thread holds
/// it for as long as the device runs.
pub type ServoCallback = Box<dyn FnMut(&DeviceState) -> PushReply + Send + 'static>;

/// A device whose own scheduler calls the servo at its rate.
pub trait PushDevice: Send {
    /// Starts the scheduler with `servo` as its callback and returns when the callback answers
    /// `go_on: false` (having set the force to zero), or with an error when the device faults.
    fn run(&mut self, servo: ServoCallback) -> Result<(), HapticsError>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_never_exceed_the_table() {
        let omni = DeviceKind::PhantomOmni.table_limits();
        // A device that reports more gets the table's figure; less, its own.
        let more = DeviceLimits::for_device(DeviceKind::PhantomOmni, Some(10.0), Some(5000.0));
        assert_eq!(more, omni);
        let less = DeviceLimits::for_device(DeviceKind::PhantomOmni, Some(2.5), Some(300.0));
        assert_eq!(less.max_force_n, 2.5);
        assert_eq!(less.max_stiffness_n_per_m, 300.0);
        // No limit (DHD's negative), nonsense or nothing: the table.
        for r in [
            None,
            Some(-1.0),
            Some(f64::NAN),
            Some(f64::INFINITY),
            Some(0.0),
        ] {
            assert_eq!(DeviceLimits::for_device(DeviceKind::Falcon, r, r), {
                DeviceKind::Falcon.table_limits()
            });
        }
        assert_eq!(DeviceKind::Falcon.table_limits().max_force_n, 8.0);
    }
}
