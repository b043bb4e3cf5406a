//! The one place a device named on the command line is opened. The vendor drivers
//! (OpenHaptics HD for the Phantom and Touch, Force Dimension DHD for the Falcon) live in
//! `xr-bindings` and are wired in here; until they are, asking for one is a clear error that
//! names its library.

use super::device::{HapticDevice, HapticsError};
use super::simulated::{Script, SimulatedStylus, StylusParams};

/// A device the command line can ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceChoice {
    /// The simulated stylus, playing [`Script::press`].
    Sim,
    /// A Phantom Omni or Touch through OpenHaptics HD (`libHD.so`).
    Phantom,
    /// A Novint Falcon (or omega) through Force Dimension DHD (`libdhd.so`).
    Falcon,
}

impl DeviceChoice {
    /// Its name on the command line.
    pub fn flag(self) -> &'static str {
        match self {
            DeviceChoice::Sim => "sim",
            DeviceChoice::Phantom => "phantom",
            DeviceChoice::Falcon => "falcon",
        }
    }
}

/// Opens the device `choice` names.
pub fn open_device(choice: DeviceChoice) -> Result<Box<dyn HapticDevice>, HapticsError> {
    match choice {
        DeviceChoice::Sim => Ok(Box::new(SimulatedStylus::new(
            Script::press(),
            StylusParams::default(),
        ))),
        DeviceChoice::Phantom => Err(HapticsError::NotBuiltIn {
            flag: choice.flag(),
            device: "Phantom Omni / Touch",
            api: "OpenHaptics HD",
            library: "libHD.so",
        }),
        DeviceChoice::Falcon => Err(HapticsError::NotBuiltIn {
            flag: choice.flag(),
            device: "Novint Falcon",
            api: "Force Dimension DHD",
            library: "libdhd.so",
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vendor_devices_are_a_clear_error_naming_their_library() {
        let sim = open_device(DeviceChoice::Sim).map(|d| d.limits().max_force_n);
        assert_eq!(sim.ok(), Some(3.3));
        for (c, lib) in [
            (DeviceChoice::Phantom, "libHD"),
            (DeviceChoice::Falcon, "libdhd"),
        ] {
            let e = open_device(c)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(e.contains(lib) && e.contains(c.flag()), "{e}");
        }
    }
}
