//! The `vesalius` command line: subcommands parsed with clap, typed errors, and exit codes
//! 0 (success), 1 (failure), 2 (usage), 128 + N after signal N ended a session cleanly, and
//! 141 when standard output is a closed pipe (the command stops quietly, as if by SIGPIPE).

#[macro_use]
mod output;
mod bench;
mod calibrate;
mod haptics;
mod precompute;
mod profile;
mod records;
mod session;
mod tools;

use clap::builder::{PossibleValue, PossibleValuesParser};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use vesalius::scenario::InputError;
use vesalius::session::SessionError;

/// Open-source virtual-reality trainer for minimally invasive surgery.
#[derive(Debug, Parser)]
#[command(
    name = "vesalius",
    version,
    propagate_version = true,
    max_term_width = 100
)]
#[command(
    after_help = "Outputs (--out DIR): report.json, events.jsonl, input.vtrace (streamed while the \
                  session runs), timing.json; frames/ and profiler.csv when rendering."
)]
pub struct Cli {
    /// Rayon worker threads (default: all cores); results do not depend on it.
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Diagnostics on standard error at this level (error, warn, info, debug, trace) or by
    /// directives (vesalius::sim=debug); default: RUST_LOG, else warn.
    #[arg(long, global = true, value_name = "LEVEL")]
    log: Option<String>,
    /// Write a Chrome trace of every span (each model's step, interaction, render pass, the
    /// servo loop) to FILE; Perfetto (ui.perfetto.dev) or chrome://tracing opens it.
    #[arg(long, global = true, value_name = "FILE")]
    profile_trace: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run every procedure's demo trace headless; reports under DIR/<procedure>/.
    Demo {
        /// Output folder.
        #[arg(long, value_name = "DIR", default_value = "vesalius-demo")]
        out: PathBuf,
        /// Store every session, as trainee 'demo', in this records file (default:
        /// DIR/records.sqlite).
        #[arg(long, value_name = "FILE")]
        records: Option<PathBuf>,
        /// `cpu`: each procedure's preset for machines without a GPU, where it has one.
        #[arg(long, value_enum)]
        preset: Option<PresetArg>,
        /// Where the models with a GPU path step (default: each scenario's `compute`, `auto`):
        /// `auto` the GPU on a real one and the CPU on a software adapter, `cpu`, or `gpu` on
        /// whatever Vulkan adapter there is.
        #[arg(long, value_enum)]
        compute: Option<ComputeArg>,
    },
    /// A session: in a desktop window (default), headless with a trace, or in a headset.
    Run(Box<RunArgs>),
    /// The recorded session again, bit for bit: the same report.json and events.jsonl.
    Replay {
        /// A recording (input.vtrace) written by run or replay.
        recording: PathBuf,
        /// Output folder (not the recording's own).
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
        /// Also render N evenly spaced stereo frames of the replayed session into
        /// DIR/frames/ and DIR/profiler.csv (the session's bytes are the same either way).
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=10_000))]
        frames: Option<u32>,
        /// Eye size of those frames in pixels (default: the Vive's 1080x1200).
        #[arg(long, value_name = "WxH", value_parser = parse_size, requires = "frames")]
        eye_size: Option<(u32, u32)>,
        /// Score the replayed session with this assessment tree instead of the procedure's
        /// own (assets/assessment/*.toml): an old session scored again.
        #[arg(long, value_name = "FILE")]
        assessment: Option<PathBuf>,
        /// Where the models with a GPU path step (default: as the recording's scenario says);
        /// on another backend or adapter than the recording's, the report says that its
        /// bytes may differ.
        #[arg(long, value_enum)]
        compute: Option<ComputeArg>,
    },
    /// Validate scenarios, keyframed traces, recordings, interaction profiles, simulated
    /// runtime settings, assessment trees and questionnaires; errors name the file, the key
    /// and what is expected.
    Check {
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
    },
    /// Step rates of each model and of the whole procedure at the scenario's sizes.
    Bench {
        /// One procedure (default: every registered one).
        #[arg(value_parser = procedures())]
        procedure: Option<String>,
        /// One JSON object a line.
        #[arg(long)]
        json: bool,
        /// `cpu`: the procedure's preset for machines without a GPU, where it has one.
        #[arg(long, value_enum)]
        preset: Option<PresetArg>,
        /// A scenario file to bench instead of the procedure's own (one procedure only);
        /// `--preset` is laid over it.
        #[arg(long, value_name = "FILE", requires = "procedure")]
        scenario: Option<PathBuf>,
        /// Where the tissue models step: `cpu` (the demo's own lines), or `gpu`: the GPU
        /// compute path's lines of the models that have one, on the first Vulkan adapter
        /// (a real GPU, else lavapipe), checked against the CPU's step.
        #[arg(long, value_enum, default_value_t = ComputeArg::Cpu)]
        compute: ComputeArg,
    },
    /// Render the demo mid-task and print the Unity-profiler counters beside the paper's.
    Profile {
        /// The procedure (default: the first registered).
        #[arg(value_parser = procedures())]
        procedure: Option<String>,
        /// Print JSON (ours under "vesalius").
        #[arg(long)]
        json: bool,
        /// Eye size in pixels (default: the Vive's 1080x1200).
        #[arg(long, value_name = "WxH", value_parser = parse_size)]
        eye_size: Option<(u32, u32)>,
        /// Two render passes instead of one multiview pass.
        #[arg(long)]
        two_pass: bool,
        /// Then draw frames at the headset's 90 Hz for this many seconds while the simulation
        /// goes on beside them in real time, and report their times, whether the
        /// simulation kept up and how often a fresh force reached the haptic channel (0:
        /// leave them out).
        #[arg(long, value_name = "SECONDS", default_value_t = 3.0)]
        beside: f64,
        /// `cpu`: the procedure's preset for machines without a GPU, where it has one.
        #[arg(long, value_enum)]
        preset: Option<PresetArg>,
        /// Where the models with a GPU path step (default: the scenario's `compute`, `auto`).
        #[arg(long, value_enum)]
        compute: Option<ComputeArg>,
        /// The models with a GPU path step on the frames' own device (one wgpu device, one
        /// queue for frames and steps) rather than on a device of their own on the same
        /// adapter: to measure what each costs the frames and the forces.
        #[arg(long)]
        share_device: bool,
    },
    /// Every model's reference cases: reference, measured, relative error, tolerance and
    /// simulated seconds per wall second; fails if any case is outside its tolerance.
    Verify {
        /// One JSON object a case.
        #[arg(long)]
        json: bool,
        /// Also run the cases where the model is known to disagree with physics (listed
        /// separately; they do not fail the command).
        #[arg(long)]
        known_failures: bool,
        /// `gpu`: the cases of the models' GPU compute path instead, on the first Vulkan
        /// adapter (a real GPU, else lavapipe).
        #[arg(long, value_enum, default_value_t = ComputeArg::Cpu)]
        compute: ComputeArg,
        /// `cpu`: also the procedures' cases at the sizes of their CPU presets.
        #[arg(long, value_enum)]
        preset: Option<PresetArg>,
    },
    /// The 1 kHz force-feedback servo loop against a procedure stepping on its own thread;
    /// prints rate_hz, period_p50_error_ms, period_p99_error_ms, max_force_n, clamps and
    /// stalls (and more), one `key value` a line.
    Haptics {
        /// The device: the simulated stylus, or a Phantom / Falcon.
        #[arg(long, value_enum)]
        device: haptics::DeviceArg,
        /// With --device phantom: its name as Touch Setup shows it (default: HD's default
        /// device).
        #[arg(long, value_name = "NAME")]
        hd_name: Option<String>,
        /// The procedure the stylus works in.
        #[arg(long, value_parser = procedures(), default_value = "sandbox")]
        procedure: String,
        /// How long the servo loop runs, seconds.
        #[arg(long, value_name = "S", value_parser = positive_seconds, default_value_t = 3.0,
              allow_negative_numbers = true)]
        seconds: f64,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Build a procedure's precomputed model into the cache, with a progress bar (the
    /// myotomy's boundary-element responses; sessions build it on first use otherwise). A
    /// cache made from other inputs, of another format or failing its checksum is rebuilt.
    Precompute {
        #[arg(value_parser = PossibleValuesParser::new(precompute::names()))]
        procedure: String,
        /// The cache file (default: $VESALIUS_CACHE_DIR, $XDG_CACHE_HOME/vesalius or
        /// ~/.cache/vesalius, then <procedure>.bem).
        #[arg(long, value_name = "FILE")]
        cache: Option<PathBuf>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// A session's report as one self-contained HTML page: score tree, level, metrics
    /// against the references, plots over time, key frames.
    Report {
        /// An output folder (report.json, events.jsonl, frames/), or a session id in the
        /// records.
        session: String,
        /// The page to write.
        #[arg(long, value_name = "FILE")]
        html: PathBuf,
        /// The records to look a session id up in (default: $VESALIUS_RECORDS, else
        /// vesalius-demo/records.sqlite).
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
    },
    /// The learning centre's records: trainees and their scored sessions (an SQLite file,
    /// owner-only; --db or $VESALIUS_RECORDS, default vesalius-demo/records.sqlite).
    #[command(subcommand)]
    Records(records::RecordsCommand),
    /// The simulated OpenXR runtime.
    #[command(name = "xr-sim", subcommand)]
    XrSim(XrSimCommand),
}

#[derive(Debug, Subcommand)]
enum XrSimCommand {
    /// Write the runtime's manifest (default: beside its library) and print its path, for
    /// XR_RUNTIME_JSON.
    Manifest {
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
    },
}

/// `--preset`: a procedure's scenario preset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum PresetArg {
    /// For machines without a GPU: coarser models, faster on the CPU.
    Cpu,
}

/// `--compute`: where the tissue models step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum ComputeArg {
    /// The GPU where the adapter is a real GPU, the CPU on a software one.
    Auto,
    Cpu,
    Gpu,
}

impl From<ComputeArg> for vesalius::scenario::Compute {
    fn from(c: ComputeArg) -> Self {
        match c {
            ComputeArg::Auto => vesalius::scenario::Compute::Auto,
            ComputeArg::Cpu => vesalius::scenario::Compute::Cpu,
            ComputeArg::Gpu => vesalius::scenario::Compute::Gpu,
        }
    }
}

/// `--xr-coupling`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum CouplingArg {
    Paced,
    Lockstep,
}

impl From<CouplingArg> for vesalius::xr::Coupling {
    fn from(c: CouplingArg) -> Self {
        match c {
            CouplingArg::Paced => vesalius::xr::Coupling::Paced,
            CouplingArg::Lockstep => vesalius::xr::Coupling::Lockstep,
        }
    }
}

#[derive(Debug, Args)]
struct RunArgs {
    /// The procedure.
    #[arg(value_parser = procedures())]
    procedure: String,
    /// `cpu`: the procedure's preset for machines without a GPU (coarser models, faster on
    /// the CPU), laid over the scenario; the recording embeds the result.
    #[arg(long, value_enum)]
    preset: Option<PresetArg>,
    /// Where the models with a GPU path step (default: the scenario's `compute`, `auto`):
    /// `auto` the GPU on a real one and the CPU on a software adapter, `cpu`, or `gpu` on
    /// whatever Vulkan adapter there is (lavapipe included); the recording embeds the choice.
    #[arg(long, value_enum)]
    compute: Option<ComputeArg>,
    /// No window: play --trace as fast as possible.
    #[arg(long, conflicts_with_all = ["xr", "xr_sim"])]
    headless: bool,
    /// A keyframed trace (assets/traces/): drives the instruments (headless or window).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["xr", "xr_sim"])]
    trace: Option<PathBuf>,
    /// Output folder: made and tested before the first step; the recording streams into it.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// A scenario file (default: the procedure's own).
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Pace the headless session against the wall clock.
    #[arg(long, requires = "headless")]
    realtime: bool,
    /// Score the session (headless or in a headset) with this assessment tree instead of the
    /// procedure's own (assets/assessment/*.toml); its rules give the instructions
    #[arg(long, value_name = "FILE", requires = "headless")]
    assessment: Option<PathBuf>,
    /// Store the session (headless or in the window) in the learning centre's records (this
    /// SQLite file) for --trainee; the window's Learning Centre panel shows them.
    #[arg(long, value_name = "FILE", requires_all = ["out", "trainee"])]
    records: Option<PathBuf>,
    /// The trainee's pseudonymous id (letters, digits, '-', '_', '.').
    #[arg(long, value_name = "ID", requires = "records")]
    trainee: Option<String>,
    /// Also render N evenly spaced stereo frames into DIR/frames/ and DIR/profiler.csv.
    #[arg(long, value_name = "N", requires_all = ["headless", "out"],
          value_parser = clap::value_parser!(u32).range(1..=10_000))]
    frames: Option<u32>,
    /// Eye size in pixels (default: the Vive's 1080x1200, or the runtime's under XR).
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    eye_size: Option<(u32, u32)>,
    /// In the headset of the active OpenXR runtime (SteamVR, Monado).
    #[arg(long, conflicts_with = "xr_sim")]
    xr: bool,
    /// Under the simulated OpenXR runtime playing TRACE; its logs go to DIR/xr-sim/.
    #[arg(long, value_name = "TRACE", requires = "out")]
    xr_sim: Option<PathBuf>,
    /// Under XR: end after S simulated seconds (default: when the runtime ends it, or the
    /// --xr-sim trace's length).
    #[arg(long, value_name = "S", value_parser = positive_seconds, allow_negative_numbers = true)]
    xr_duration: Option<f64>,
    /// Under XR: whether frames wait for the simulation. `paced` (the default with --xr):
    /// never, each frame shows the newest state; `lockstep` (the default with --xr-sim, whose
    /// runtime's clock runs as fast as frames are made): each frame shows its own time.
    #[arg(long, value_enum, value_name = "HOW")]
    xr_coupling: Option<CouplingArg>,
    /// Under XR, paced: the most the simulation may fall behind the frames, seconds (default
    /// 0.1). A simulation slower than real time then runs slower than the headset's clock
    /// instead of drawing an ever older state; `inf`: no bound, every frame's time is stepped.
    #[arg(long, value_name = "SECONDS")]
    xr_max_lag: Option<f64>,
    /// Under XR or with --haptics: no desktop window.
    #[arg(long)]
    no_window: bool,
    /// Save the whole window as PNG when the session ends (or at --screenshot-at), then close.
    #[arg(long, value_name = "FILE", conflicts_with = "headless")]
    screenshot: Option<PathBuf>,
    /// When to take the screenshot, simulated seconds.
    #[arg(long, value_name = "S", requires = "screenshot", value_parser = seconds,
          allow_negative_numbers = true)]
    screenshot_at: Option<f64>,

    /// Desktop mode: begin at once, without the start screen (scripted sessions)
    #[arg(long)]
    start: bool,
    /// Window size in points.
    #[arg(long, value_name = "WxH", value_parser = parse_size, default_value = "1600x900")]
    window_size: (u32, u32),
    /// The longest session allowed, seconds: traces with later keys are refused (4 h).
    #[arg(long, value_name = "S", value_parser = positive_seconds, default_value_t = vesalius::session::DEFAULT_MAX_SESSION_S)]
    max_session: f64,
    /// Force-feedback devices driving the instruments, one or two of sim, phantom, falcon
    /// (two: left and right hand), in the desktop window where there is a display (else, or
    /// with --no-window, without one); ends when the window closes, after --seconds, or at
    /// Ctrl-C. With --xr (or --xr-sim): in the headset, the other hand on its controller.
    #[arg(long, value_name = "DEVICES", value_enum, value_delimiter = ',',
          conflicts_with_all = ["headless", "trace"])]
    haptics: Vec<haptics::DeviceArg>,
    /// With --haptics: the Phantoms' device names as Touch Setup shows them, in the order the
    /// Phantoms are listed (default: HD's default device; two Phantoms need both names).
    #[arg(
        long,
        value_name = "NAMES",
        value_delimiter = ',',
        requires = "haptics"
    )]
    hd_names: Vec<String>,
    /// With --haptics: field metres per device metre (below 1: finer motion, softer feel).
    #[arg(long, value_name = "S", requires = "haptics", default_value_t = 1.0,
          value_parser = positive_scale)]
    workspace_scale: f64,
    /// With --haptics: how long the session runs, simulated seconds (default: until the
    /// window closes; without a window, 60). In the headset, --xr-duration says it.
    #[arg(long, value_name = "S", requires = "haptics", conflicts_with_all = ["xr", "xr_sim"],
          value_parser = positive_seconds, allow_negative_numbers = true)]
    seconds: Option<f64>,
}

/// A command's failure, and the exit code it gives.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The command line asks for something that cannot be: exit 2.
    #[error("{0}")]
    Usage(String),
    #[error(transparent)]
    Input(#[from] InputError),
    #[error(transparent)]
    Session(#[from] SessionError),
    /// A session in a headset (`run --xr`).
    #[error(transparent)]
    Xr(#[from] vesalius::xr::XrRunError),
    /// A session in the desktop window.
    #[error(transparent)]
    Window(#[from] vesalius::ui::window::WindowError),
    #[error(transparent)]
    Bench(#[from] vesalius::sim::BenchError),
    /// `--log` or `--profile-trace`.
    #[error(transparent)]
    Diagnostics(#[from] vesalius::diagnostics::DiagnosticsError),
    #[error(transparent)]
    Render(#[from] vesalius::render::RenderError),
    /// A procedure refused its (checked) scenario.
    #[error(transparent)]
    Build(#[from] vesalius::procedures::BuildError),
    /// The simulated runtime's settings (`run --xr-sim` keeps those named by
    /// `VESALIUS_XR_SIM_CONFIG`).
    #[error(transparent)]
    SimSettings(#[from] vesalius_sim_runtime::ConfigError),
    /// A force-feedback device or the servo loop.
    #[error(transparent)]
    Haptics(#[from] vesalius::haptics::HapticsError),
    /// The learning centre's records.
    #[error(transparent)]
    Records(#[from] vesalius::records::RecordsError),
    /// A failure of the command itself (a file it writes, a child process), in words.
    #[error("{0}")]
    Failed(String),
    /// Standard output was closed (`| head`): stop quietly.
    #[error("standard output is closed")]
    ClosedPipe,
    /// A signal ended the session; its files were written.
    #[error("the session was interrupted by {name}; its files were written")]
    Interrupted { signal: i32, name: &'static str },
}

impl CliError {
    fn exit_code(&self) -> u8 {
        match self {
            CliError::Usage(_) => 2,
            CliError::ClosedPipe => 141,
            CliError::Interrupted { signal, .. } => u8::try_from(128 + signal).unwrap_or(1),
            _ => 1,
        }
    }
}

/// The registered procedures, with their titles for `--help`.
fn procedures() -> PossibleValuesParser {
    PossibleValuesParser::new(
        vesalius::registry::REGISTRY
            .iter()
            .map(|p| PossibleValue::new(p.name).help(p.title)),
    )
}

/// A flag's value that is not what the flag takes.
#[derive(Debug, thiserror::Error)]
#[error("expected {expected}, got '{got}'")]
pub struct BadValue {
    expected: &'static str,
    got: String,
}

fn bad(expected: &'static str, got: &str) -> BadValue {
    BadValue {
        expected,
        got: got.to_string(),
    }
}

/// WIDTHxHEIGHT in pixels, each 16 to 8192.
fn parse_size(v: &str) -> Result<(u32, u32), BadValue> {
    v.split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .filter(|&(w, h)| (16..=8192).contains(&w) && (16..=8192).contains(&h))
        .ok_or_else(|| bad("WIDTHxHEIGHT in pixels, each 16 to 8192", v))
}

/// Seconds, 0 or more and finite.
fn seconds(v: &str) -> Result<f64, BadValue> {
    v.parse::<f64>()
        .ok()
        .filter(|s| s.is_finite() && *s >= 0.0)
        .ok_or_else(|| bad("seconds (0 or more)", v))
}

/// Seconds, more than 0 and finite.
fn positive_seconds(v: &str) -> Result<f64, BadValue> {
    v.parse::<f64>()
        .ok()
        .filter(|s| s.is_finite() && *s > 0.0)
        .ok_or_else(|| bad("seconds greater than 0", v))
}

fn positive_scale(v: &str) -> Result<f64, BadValue> {
    v.parse::<f64>()
        .ok()
        .filter(|s| s.is_finite() && *s >= 0.01 && *s <= 100.0)
        .ok_or_else(|| bad("a scale from 0.01 to 100", v))
}

/// Parses the command line, runs the command and turns its result into an exit code.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) if e.use_stderr() => {
            // Usage errors go to standard error with exit 2; a closed stream is no panic.
            tell!("{}", with_suggestion(&e).trim_end());
            return ExitCode::from(2);
        }
        Err(e) => {
            // Help and version go to standard output.
            let _ = e.print();
            return ExitCode::SUCCESS;
        }
    };
    match dispatch(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(CliError::ClosedPipe) => ExitCode::from(141),
        Err(e) => {
            output::error(&e);
            ExitCode::from(e.exit_code())
        }
    }
}

/// A usage error's text, with a suggestion for a mistyped command where clap has none (its
/// similarity measure misses short words with a letter dropped: `rn` for `run`).
fn with_suggestion(e: &clap::Error) -> String {
    use clap::CommandFactory;
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    let text = e.render().to_string();
    if e.kind() != ErrorKind::InvalidSubcommand || text.contains("tip:") {
        return text;
    }
    let Some(ContextValue::String(typed)) = e.get(ContextKind::InvalidSubcommand) else {
        return text;
    };
    let cmd = Cli::command();
    let best = cmd
        .get_subcommands()
        .map(|c| (edit_distance(typed, c.get_name()), c.get_name().to_string()))
        .filter(|(d, name)| *d <= 2 && *d < name.len())
        .min();
    match best {
        Some((_, name)) => text.replacen(
            "\n\nUsage:",
            &format!("\n\n  tip: a similar subcommand exists: '{name}'\n\nUsage:"),
            1,
        ),
        None => text,
    }
}

/// Levenshtein distance between two words.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for j in 0..b.len() {
            let here = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != b[j]))
                .min(row[j] + 1)
                .min(here + 1);
            prev = here;
        }
    }
    row[b.len()]
}

fn dispatch(cli: Cli) -> Result<(), CliError> {
    // Written when the command ends (the guard drops at the end of this function).
    let _trace = vesalius::diagnostics::init(cli.log.as_deref(), cli.profile_trace.as_deref())?;
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(usize::from(n))
            .build_global()
            .map_err(|e| CliError::Failed(format!("cannot start {n} threads: {e}")))?;
    }
    vesalius::session::interrupt::install()
        .map_err(|e| CliError::Failed(format!("cannot install signal handlers: {e}")))?;
    match cli.command {
        Command::Demo {
            out,
            records,
            preset,
            compute,
        } => session::demo(&out, records.as_deref(), preset, compute),
        Command::Run(args) => session::run(*args),
        Command::Replay {
            recording,
            out,
            frames,
            eye_size,
            assessment,
            compute,
        } => session::replay(
            &recording,
            &out,
            frames,
            eye_size,
            assessment.as_deref(),
            compute,
        ),
        Command::Check { files } => tools::check(&files),
        Command::Bench {
            procedure,
            json,
            preset,
            scenario,
            compute,
        } => tools::bench(
            procedure.as_deref(),
            json,
            preset,
            scenario.as_deref(),
            compute,
        ),
        Command::Profile {
            procedure,
            json,
            eye_size,
            two_pass,
            beside,
            preset,
            compute,
            share_device,
        } => profile::profile(
            procedure.as_deref(),
            json,
            (
                eye_size.unwrap_or(vesalius::render::camera::VIVE_EYE_SIZE),
                two_pass,
                share_device,
            ),
            (beside, preset, compute),
        ),
        Command::Verify {
            json,
            known_failures,
            compute,
            preset,
        } => tools::verify(json, known_failures, compute, preset),
        Command::Haptics {
            device,
            hd_name,
            procedure,
            seconds,
            json,
        } => haptics::haptics(device, hd_name.as_deref(), &procedure, seconds, json),
        Command::Precompute {
            procedure,
            cache,
            json,
        } => precompute::precompute(&procedure, cache, json),
        Command::Records(c) => records::run(c),
        Command::Report { session, html, db } => records::report(&session, &html, db),
        Command::XrSim(XrSimCommand::Manifest { out }) => {
            let path = tools::xr_sim_manifest(out)?;
            say!("{}", path.display());
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn a_typo_is_a_usage_error_with_a_suggestion() {
        for (typed, meant) in [("rn", "run"), ("bnch", "bench"), ("reply", "replay")] {
            let e = Cli::try_parse_from(["vesalius", typed]).expect_err("typo");
            assert!(e.use_stderr());
            let text = with_suggestion(&e);
            assert!(text.contains(&format!("'{meant}'")), "{text}");
        }
        let e = Cli::try_parse_from(["vesalius", "xyzzy"]).expect_err("unknown");
        assert!(!with_suggestion(&e).contains("tip:"));
        assert_eq!(edit_distance("rn", "run"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
    }

    #[test]
    fn run_help_lists_the_registered_procedures() {
        let help = Cli::command()
            .find_subcommand_mut("run")
            .map(|c| c.render_long_help().to_string())
            .unwrap_or_default();
        for p in vesalius::registry::REGISTRY {
            assert!(help.contains(p.name) && help.contains(p.title), "{help}");
        }
    }

    #[test]
    fn conflicting_and_incomplete_flags_are_usage_errors() {
        let p = vesalius::registry::REGISTRY[0].name;
        for args in [
            &["vesalius", "run", p, "--xr", "--headless"][..],
            &["vesalius", "run", p, "--frames", "3", "--headless"],
            &["vesalius", "run", p, "--xr-sim", "t.toml"],
            &["vesalius", "run", p, "--screenshot-at", "1"],
            &["vesalius", "run", p, "--eye-size", "10x10"],
            &["vesalius", "run", "no-such-procedure"],
            &["vesalius", "--threads", "0", "demo"],
        ] {
            let e = Cli::try_parse_from(args).expect_err("refused");
            assert!(e.use_stderr(), "{args:?}");
        }
        let ok = Cli::try_parse_from(["vesalius", "run", p, "--headless"]);
        assert!(ok.is_ok());
    }
}
