//! `haptics`: the 1 kHz servo loop against a procedure, with its timing and force figures.

use super::{CliError, RunArgs};
use vesalius::haptics::{
    BoundOptions, DeviceChoice, SafetyParams, StandOptions, open_device, run_bound, run_stand,
};
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

/// `run <procedure> --haptics D[,D]`: a recorded session driven by the devices, then its
/// report and one line per device.
pub fn run_with_devices(a: &RunArgs) -> Result<(), CliError> {
    if a.haptics.len() > 2 {
        return Err(CliError::Usage(format!(
            "--haptics: one or two devices (one per hand), got {}",
            a.haptics.len()
        )));
    }
    if a.haptics
        .iter()
        .filter(|d| **d == DeviceArg::Phantom)
        .count()
        > 1
    {
        return Err(CliError::Usage(
            "--haptics phantom,phantom: two OpenHaptics devices share HD's one scheduler, \
             which this version drives for one device only; use one Phantom, or a Phantom \
             and a Falcon"
                .into(),
        ));
    }
    let (file, text) = super::session::scenario_text(&a.procedure, a.scenario.as_deref())?;
    if let Some(dir) = &a.out {
        vesalius::session::prepare(dir)?;
    }
    let mut devices = Vec::new();
    for d in &a.haptics {
        devices.push(open_device((*d).into())?);
    }
    let opts = BoundOptions {
        scenario_text: &text,
        scenario_file: &file,
        out: a.out.as_deref(),
        seconds: a.seconds,
        scale: a.workspace_scale,
        safety: SafetyParams::default(),
    };
    let run = run_bound(&mut devices, &opts)?;
    super::session::finish(&run.outcome, a.out.as_deref())?;
    for d in &run.devices {
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
    super::session::interrupted()
}
