//! `haptics`: the 1 kHz servo loop against a procedure, with its timing and force figures.

use super::CliError;
use vesalius::haptics::{DeviceChoice, StandOptions, open_device, run_stand};
use vesalius::session::interrupt;

/// A device on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DeviceArg {
    /// The simulated stylus: a scripted hand presses it into the tissue and back.
    Sim,
    /// A Phantom Omni or Touch (OpenHaptics HD, libHD.so).
    Phantom,
    /// A Novint Falcon (Force Dimension DHD, libdhd.so).
    Falcon,
}

impl From<DeviceArg> for DeviceChoice {
    fn from(d: DeviceArg) -> DeviceChoice {
        match d {
            DeviceArg::Sim => DeviceChoice::Sim,
            DeviceArg::Phantom => DeviceChoice::Phantom,
            DeviceArg::Falcon => DeviceChoice::Falcon,
        }
    }
}

/// `haptics`: runs the servo loop for `seconds` and prints its figures, one `key value` a
/// line or one JSON object.
pub fn haptics(
    device: DeviceArg,
    procedure: &str,
    seconds: f64,
    json: bool,
) -> Result<(), CliError> {
    let info = vesalius::procedures::find(procedure)
        .ok_or_else(|| CliError::Usage(format!("unknown procedure '{procedure}'")))?;
    let mut dev = open_device(device.into())?;
    let r = run_stand(dev.as_mut(), &StandOptions::new(info, seconds))?;
    let s = &r.servo;
    let figures: [(&str, serde_json::Value); 13] = [
        ("rate_hz", s.rate_hz.into()),
        ("period_p50_error_ms", s.period_p50_error_ms.into()),
        ("period_p99_error_ms", s.period_p99_error_ms.into()),
        ("max_force_n", s.max_force_n.into()),
        ("clamps", s.clamps.into()),
        ("stalls", s.stalls.into()),
        ("ticks", s.ticks.into()),
        ("clamped_ticks", s.clamped_ticks.into()),
        ("non_finite", s.non_finite.into()),
        ("skipped_deadlines", s.skipped_deadlines.into()),
        ("limit_force_n", s.limit_force_n.into()),
        ("sim_steps", r.sim_steps.into()),
        ("sim_s", r.sim_s.into()),
    ];
    if json {
        let map: serde_json::Map<String, serde_json::Value> = figures
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect();
        say!("{}", serde_json::Value::Object(map));
    } else {
        for (k, v) in figures {
            match v.as_f64().filter(|_| !v.is_u64()) {
                Some(x) => say!("{k} {x:.4}"),
                None => say!("{k} {v}"),
            }
        }
    }
    match interrupt::interrupted() {
        Some(signal) => Err(CliError::Interrupted {
            signal,
            name: interrupt::signal_name(signal),
        }),
        None => Ok(()),
    }
}
