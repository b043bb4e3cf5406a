//! `haptics`: the 1 kHz servo loop against a procedure, with its timing and force figures.

use super::{CliError, RunArgs};
use vesalius::haptics::{
    BoundOptions, DeviceChoice, DeviceRun, RigOptions, SafetyParams, StandOptions, open_device,
    run_bound, run_stand,
};
use vesalius::session::interrupt;
use vesalius::ui::window::WindowDevices;

/// A device on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DeviceArg {
    /// The simulated stylus: a scripted hand presses it into the tissue and back.
    Sim,
    /// A Phantom Omni or Touch (OpenHaptics HD, libHD.so).
    Phantom,
    /// A Novint Falcon (Force Dimension DHD, libdhd.so).
    Falcon,
    /// The procedure's own device, the one its paper used (a Falcon or a Phantom).
    Default,
}

impl DeviceArg {
    /// `Default` made the procedure's own device.
    fn resolved(self, info: &vesalius::procedures::ProcedureInfo) -> DeviceArg {
        match (self, info.options.haptic_device) {
            (DeviceArg::Default, DeviceChoice::Sim) => DeviceArg::Sim,
            (DeviceArg::Default, DeviceChoice::Phantom) => DeviceArg::Phantom,
            (DeviceArg::Default, DeviceChoice::Falcon) => DeviceArg::Falcon,
            (d, _) => d,
        }
    }
}

impl From<DeviceArg> for DeviceChoice {
    fn from(d: DeviceArg) -> DeviceChoice {
        match d {
            DeviceArg::Sim => DeviceChoice::Sim,
            DeviceArg::Phantom => DeviceChoice::Phantom,
            DeviceArg::Falcon => DeviceChoice::Falcon,
            // Resolved against the procedure before it gets here; a Phantom otherwise.
            DeviceArg::Default => DeviceChoice::Phantom,
        }
    }
}

/// `haptics`: runs the servo loop for `seconds` and prints its figures, one `key value` a
/// line or one JSON object.
pub fn haptics(
    device: DeviceArg,
    hd_name: Option<&str>,
    procedure: &str,
    seconds: f64,
    json: bool,
) -> Result<(), CliError> {
    let info = vesalius::registry::find(procedure)
        .ok_or_else(|| CliError::Usage(format!("unknown procedure '{procedure}'")))?;
    let device = device.resolved(info);
    if hd_name.is_some() && device != DeviceArg::Phantom {
        return Err(CliError::Usage(
            "--hd-name names a Phantom: it goes with --device phantom".into(),
        ));
    }
    let mut dev = open_device(device.into(), hd_name)?;
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

/// `run <procedure> --haptics D[,D]`: a recorded session driven by the devices, in the desktop
/// window where there is a display (and no `--no-window`), else without one; then its report
/// and one line per device.
pub fn run_with_devices(a: &RunArgs) -> Result<(), CliError> {
    let (chosen, names) = chosen_devices(a)?;
    let windowed = !a.no_window && super::session::display_available();
    if !windowed && a.screenshot.is_some() {
        return Err(CliError::Usage(
            "--screenshot needs a window: no DISPLAY (try xvfb-run), or drop --no-window".into(),
        ));
    }
    let preset =
        super::session::preset_for_auto(&a.procedure, a.scenario.as_deref(), a.preset, a.compute);
    let (file, text) =
        super::session::scenario_text(&a.procedure, a.scenario.as_deref(), preset, a.compute)?;
    if let Some(dir) = &a.out {
        vesalius::session::prepare(dir)?;
    }
    let devices = open_devices(&chosen, &names)?;
    if windowed {
        let seconds = a.seconds;
        let options = RigOptions {
            scale: a.workspace_scale,
            safety: SafetyParams::default(),
            // The servo loops end with the window's session; a backstop for a day's use.
            backstop_s: seconds.map_or(24.0 * 3600.0, |s| 4.0 * s + 10.0),
        };
        let window = WindowDevices {
            devices,
            options,
            until_s: seconds,
        };
        return super::session::run_window(a, None, Some(window));
    }
    let opts = BoundOptions {
        scenario_text: &text,
        scenario_file: &file,
        out: a.out.as_deref(),
        seconds: a.seconds.unwrap_or(DEFAULT_SECONDS),
        scale: a.workspace_scale,
        safety: SafetyParams::default(),
    };
    let run = run_bound(devices, &opts)?;
    super::session::finish(&run.outcome, a.out.as_deref())?;
    say_devices(&run.devices)?;
    super::session::interrupted()
}

/// `--haptics` resolved against the procedure (at most two devices), with each Phantom's HD
/// name.
fn chosen_devices(a: &RunArgs) -> Result<(Vec<DeviceArg>, Vec<Option<String>>), CliError> {
    if a.haptics.len() > 2 {
        return Err(CliError::Usage(format!(
            "--haptics: one or two devices (one per hand), got {}",
            a.haptics.len()
        )));
    }
    let info = vesalius::registry::find(&a.procedure)
        .ok_or_else(|| CliError::Usage(format!("no procedure '{}'", a.procedure)))?;
    let chosen: Vec<DeviceArg> = a.haptics.iter().map(|d| d.resolved(info)).collect();
    let names = hd_names(&chosen, &a.hd_names)?;
    Ok((chosen, names))
}

fn open_devices(
    chosen: &[DeviceArg],
    names: &[Option<String>],
) -> Result<Vec<Box<dyn vesalius::haptics::HapticDevice>>, CliError> {
    let mut devices = Vec::new();
    for (d, name) in chosen.iter().zip(names) {
        devices.push(open_device((*d).into(), name.as_deref())?);
    }
    Ok(devices)
}

/// `run <procedure> --xr --haptics D[,D]`: the devices for a session in the headset (none
/// without `--haptics`).
pub fn xr_devices(a: &RunArgs) -> Result<Option<vesalius::xr::XrDevices>, CliError> {
    if a.haptics.is_empty() {
        return Ok(None);
    }
    let (chosen, names) = chosen_devices(a)?;
    Ok(Some(vesalius::xr::XrDevices {
        devices: open_devices(&chosen, &names)?,
        options: RigOptions {
            scale: a.workspace_scale,
            safety: SafetyParams::default(),
            // The servo loops end with the session, however slowly its frames come (the
            // simulated runtime's clock waits for each frame drawn); a backstop for a day's
            // use.
            backstop_s: 24.0 * 3600.0,
        },
    }))
}

/// The command line's words for `devices`, passed on to the process that runs a session
/// under the simulated runtime.
pub fn device_words(devices: &[DeviceArg]) -> String {
    devices
        .iter()
        .map(|d| match d {
            DeviceArg::Sim => "sim",
            DeviceArg::Phantom => "phantom",
            DeviceArg::Falcon => "falcon",
            DeviceArg::Default => "default",
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// How long a device-driven session without a window runs unless told, simulated seconds.
const DEFAULT_SECONDS: f64 = 60.0;

/// One line per device: rate, timing, peak force, clamps, stalls, clutch uses.
pub fn say_devices(runs: &[DeviceRun]) -> Result<(), CliError> {
    for d in runs {
        let s = &d.servo;
        say!(
            "{} on the {} hand: {:.1} Hz, period error p99 {:.3} ms, max force {:.2} N (limit {:.1} N), {} clamps, {} stalls, clutch let go {} times",
            d.device,
            d.hand.name(),
            s.rate_hz,
            s.period_p99_error_ms,
            s.max_force_n,
            s.limit_force_n,
            s.clamps,
            s.stalls,
            d.reanchors
        );
    }
    Ok(())
}

/// The HD device name for each device of `devices` (`None` but for Phantoms): `names` in the
/// order the Phantoms are listed. One Phantom may go unnamed (HD's default device); two must
/// be named, since HD opens its default device once.
fn hd_names(devices: &[DeviceArg], names: &[String]) -> Result<Vec<Option<String>>, CliError> {
    let phantoms = devices.iter().filter(|d| **d == DeviceArg::Phantom).count();
    if !names.is_empty() && names.len() != phantoms {
        return Err(CliError::Usage(format!(
            "--hd-names: {} name(s) for {phantoms} Phantom(s); give one per Phantom, in order",
            names.len()
        )));
    }
    if phantoms > 1 && names.is_empty() {
        return Err(CliError::Usage(
            "--haptics with two Phantoms: name them as Touch Setup shows them, e.g. \
             --hd-names \"Left Device,Right Device\" (HD opens its default device once)"
                .into(),
        ));
    }
    let mut given = names.iter();
    Ok(devices
        .iter()
        .map(|d| match d {
            DeviceArg::Phantom => given.next().cloned(),
            _ => None,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phantoms_take_their_names_in_order_and_two_need_names() {
        use DeviceArg::{Falcon, Phantom, Sim};
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(
            hd_names(&[Phantom, Phantom], &names(&["L", "R"])).ok(),
            Some(vec![Some("L".into()), Some("R".into())])
        );
        assert_eq!(
            hd_names(&[Falcon, Phantom], &names(&["R"])).ok(),
            Some(vec![None, Some("R".into())])
        );
        assert_eq!(hd_names(&[Phantom], &[]).ok(), Some(vec![None]));
        assert_eq!(hd_names(&[Sim, Sim], &[]).ok(), Some(vec![None, None]));
        for (devices, given) in [
            (&[Phantom, Phantom][..], &[][..]),
            (&[Phantom, Phantom], &["L"][..]),
            (&[Sim], &["L"][..]),
        ] {
            assert!(matches!(
                hd_names(devices, &names(given)),
                Err(CliError::Usage(_))
            ));
        }
    }
}
