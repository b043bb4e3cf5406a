//! Diagnostics through `tracing`: a log on standard error at the level `--log LEVEL` or
//! `RUST_LOG` sets (warnings by default), and with `--profile-trace FILE` a Chrome trace of
//! every span (each model's step, each interaction, the render passes, the servo loop) that
//! Perfetto or `chrome://tracing` opens, so anyone can see where a step's time goes.
//!
//! Spans below the log's level are not even created unless a trace is written: off, a span
//! costs one relaxed load at its call site. User-facing errors and progress are not
//! diagnostics and stay on standard output and error as they are.

use serde_json::{Map, Value};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;
use tracing::span::{Attributes, Id, Record};
use tracing::{Subscriber, field::Field};
use tracing_subscriber::layer::{Context, Layer, SubscriberExt};
use tracing_subscriber::registry::LookupSpan;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::{
    EnvFilter,
    filter::{LevelFilter, Targets},
};

/// Why diagnostics could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum DiagnosticsError {
    #[error(
        "--log {level}: {message} (expected a level such as warn, info, debug or trace, or directives such as vesalius::sim=trace)"
    )]
    Level { level: String, message: String },
    #[error("--profile-trace {path}: {message}")]
    Trace { path: String, message: String },
}

/// Keeps the trace file open while the program runs; dropping it closes the JSON and
/// flushes it.
#[must_use = "the trace is written when this guard drops"]
pub struct TraceGuard {
    sink: Option<Arc<Sink>>,
}

impl Drop for TraceGuard {
    fn drop(&mut self) {
        if let Some(sink) = self.sink.take() {
            sink.finish();
        }
    }
}

/// Installs the global subscriber: the log at `level` (else `RUST_LOG`, else `warn`) on
/// standard error, and a Chrome trace into `trace` if given. Once per process; a second call
/// keeps the first subscriber and only returns a guard that writes nothing.
pub fn init(level: Option<&str>, trace: Option<&Path>) -> Result<TraceGuard, DiagnosticsError> {
    let filter = match level {
        Some(l) => EnvFilter::builder()
            .parse(l)
            .map_err(|e| DiagnosticsError::Level {
                level: l.to_string(),
                message: e.to_string(),
            })?,
        None => EnvFilter::builder()
            .with_default_directive(LevelFilter::WARN.into())
            .from_env_lossy(),
    };
    let log = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .with_target(true)
        .with_filter(filter);
    let sink = match trace {
        Some(path) => Some(Arc::new(Sink::create(path)?)),
        None => None,
    };
    let chrome = sink.clone().map(|sink| ChromeLayer { sink });
    // Without a trace file nothing wants the spans below the log's level: they are then
    // never created (an absent layer would otherwise take every one, and the registry would
    // allocate each model step's span for nobody). With one, the trace takes all of ours and
    // only the warnings of the crates below us: wgpu logs every dispatch at its trace level,
    // which would slow a GPU session several times over and fill the trace with it.
    let spans = if chrome.is_some() {
        trace_targets()
    } else {
        Targets::new().with_default(LevelFilter::OFF)
    };
    let _ = tracing_subscriber::registry()
        .with(log)
        .with(chrome.with_filter(spans))
        .try_init();
    Ok(TraceGuard { sink })
}

/// What a Chrome trace takes: every span and event of our crates, warnings from the rest.
fn trace_targets() -> Targets {
    ["vesalius", "xr_bindings", "vesalius_sim_runtime"]
        .into_iter()
        .fold(Targets::new(), |t, name| {
            t.with_target(name, LevelFilter::TRACE)
        })
        .with_default(LevelFilter::WARN)
}

/// Where trace events go: one JSON object a line inside `{"traceEvents":[ ... ]}`.
struct Sink {
    path: PathBuf,
    start: Instant,
    out: Mutex<Option<BufWriter<File>>>,
    /// Whether an event has been written (for the commas).
    wrote: Mutex<bool>,
}

impl Sink {
    fn create(path: &Path) -> Result<Self, DiagnosticsError> {
        let err = |e: std::io::Error| DiagnosticsError::Trace {
            path: path.display().to_string(),
            message: e.to_string(),
        };
        let mut out = BufWriter::new(File::create(path).map_err(err)?);
        out.write_all(b"{\"displayTimeUnit\":\"ms\",\"traceEvents\":[\n")
            .map_err(err)?;
        Ok(Self {
            path: path.to_path_buf(),
            start: Instant::now(),
            out: Mutex::new(Some(out)),
            wrote: Mutex::new(false),
        })
    }

    /// Microseconds since the trace began.
    fn now_us(&self) -> f64 {
        self.start.elapsed().as_secs_f64() * 1e6
    }

    fn write(&self, event: &Value) {
        let mut out = self.out.lock().unwrap_or_else(PoisonError::into_inner);
        let Some(w) = out.as_mut() else { return };
        let mut wrote = self.wrote.lock().unwrap_or_else(PoisonError::into_inner);
        let sep: &[u8] = if *wrote { b",\n" } else { b"" };
        // A trace that cannot be written is lost, not the session: write errors are dropped.
        let _ = w
            .write_all(sep)
            .and_then(|()| serde_json::to_writer(&mut *w, event).map_err(std::io::Error::other));
        *wrote = true;
    }

    fn finish(&self) {
        let mut out = self.out.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(mut w) = out.take()
            && let Err(e) = w.write_all(b"\n]}\n").and_then(|()| w.flush())
        {
            tracing::error!(
                "the trace {} could not be finished: {e}",
                self.path.display()
            );
        }
    }
}

/// A span's fields and when it was entered.
struct SpanData {
    args: Map<String, Value>,
    entered_us: Vec<f64>,
}

struct ArgVisitor<'a>(&'a mut Map<String, Value>);

impl tracing::field::Visit for ArgVisitor<'_> {
    fn record_str(&mut self, field: &Field, value: &str) {
        self.0.insert(field.name().to_string(), Value::from(value));
    }
    fn record_u64(&mut self, field: &Field, value: u64) {
        self.0.insert(field.name().to_string(), Value::from(value));
    }
    fn record_i64(&mut self, field: &Field, value: i64) {
        self.0.insert(field.name().to_string(), Value::from(value));
    }
    fn record_f64(&mut self, field: &Field, value: f64) {
        self.0.insert(field.name().to_string(), Value::from(value));
    }
    fn record_bool(&mut self, field: &Field, value: bool) {
        self.0.insert(field.name().to_string(), Value::from(value));
    }
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        self.0
            .insert(field.name().to_string(), Value::from(format!("{value:?}")));
    }
}

/// The calling thread's CPU time so far, s: the OS's clock for the thread, which runs only
/// while the thread runs (not while it waits, or is ready but kept off its core); none where
/// the OS keeps no such clock.
pub fn thread_cpu_s() -> Option<f64> {
    #[cfg(unix)]
    {
        let t = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
        Some(t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Writes every span as a Chrome "complete" event (`ph: "X"`, start and duration in
/// microseconds, the thread it ran on, its fields as `args`) and every event as an instant
/// (`ph: "i"`).
struct ChromeLayer {
    sink: Arc<Sink>,
}

/// A small number for the current thread (Chrome's `tid`), in the order threads first trace.
fn thread_number() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(1);
    thread_local! {
        static ME: u64 = NEXT.fetch_add(1, Ordering::Relaxed);
    }
    ME.with(|m| *m)
}

impl<S> Layer<S> for ChromeLayer
where
    S: Subscriber + for<'a> LookupSpan<'a>,
{
    fn on_new_span(&self, attrs: &Attributes<'_>, id: &Id, ctx: Context<'_, S>) {
        let mut args = Map::new();
        attrs.record(&mut ArgVisitor(&mut args));
        if let Some(span) = ctx.span(id) {
            span.extensions_mut().insert(SpanData {
                args,
                entered_us: Vec::new(),
            });
        }
    }

    fn on_record(&self, id: &Id, values: &Record<'_>, ctx: Context<'_, S>) {
        if let Some(span) = ctx.span(id)
            && let Some(data) = span.extensions_mut().get_mut::<SpanData>()
        {
            values.record(&mut ArgVisitor(&mut data.args));
        }
    }

    fn on_enter(&self, id: &Id, ctx: Context<'_, S>) {
        if let Some(span) = ctx.span(id)
            && let Some(data) = span.extensions_mut().get_mut::<SpanData>()
        {
            data.entered_us.push(self.sink.now_us());
        }
    }

    fn on_exit(&self, id: &Id, ctx: Context<'_, S>) {
        let Some(span) = ctx.span(id) else { return };
        let end = self.sink.now_us();
        let (start, args) = {
            let mut ext = span.extensions_mut();
            let Some(data) = ext.get_mut::<SpanData>() else {
                return;
            };
            let Some(start) = data.entered_us.pop() else {
                return;
            };
            (start, data.args.clone())
        };
        let meta = span.metadata();
        self.sink.write(&serde_json::json!({
            "name": meta.name(),
            "cat": meta.target(),
            "ph": "X",
            "ts": start,
            "dur": end - start,
            "pid": 1,
            "tid": thread_number(),
            "args": args,
        }));
    }

    fn on_event(&self, event: &tracing::Event<'_>, _ctx: Context<'_, S>) {
        let mut args = Map::new();
        event.record(&mut ArgVisitor(&mut args));
        let meta = event.metadata();
        self.sink.write(&serde_json::json!({
            "name": meta.name(),
            "cat": meta.target(),
            "ph": "i",
            "s": "t",
            "ts": self.sink.now_us(),
            "pid": 1,
            "tid": thread_number(),
            "args": args,
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::trace_targets;
    use tracing::Level;

    #[test]
    fn a_trace_takes_our_spans_at_every_level_and_only_the_warnings_of_the_crates_below() {
        let t = trace_targets();
        for ours in ["vesalius::sim::world", "vesalius", "xr_bindings::session"] {
            assert!(t.would_enable(ours, &Level::TRACE), "{ours}");
        }
        // wgpu logs each dispatch at trace level.
        for theirs in [
            "wgpu_core::command::compute",
            "naga::front",
            "wgpu_hal::vulkan",
        ] {
            assert!(!t.would_enable(theirs, &Level::TRACE), "{theirs}");
            assert!(!t.would_enable(theirs, &Level::INFO), "{theirs}");
            assert!(t.would_enable(theirs, &Level::WARN), "{theirs}");
        }
    }
}

#[cfg(test)]
mod thread_clock_tests {
    use super::thread_cpu_s;

    #[cfg(unix)]
    #[test]
    fn the_threads_clock_runs_while_it_works_and_stands_while_it_sleeps() {
        let start = thread_cpu_s().expect("a thread clock on unix");
        // Work until the thread's clock has moved (it moves only while the thread runs).
        let mut x = 0u64;
        let mut worked = 0.0;
        while worked <= 0.0 {
            for i in 0..100_000u64 {
                x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(i));
            }
            worked = thread_cpu_s().expect("a thread clock") - start;
        }
        assert!(worked > 0.0 && worked < 60.0, "{worked} s");
        // A sleep of 200 ms costs the thread next to nothing (a wall clock would give 0.2 s).
        let before = thread_cpu_s().expect("a thread clock");
        std::thread::sleep(std::time::Duration::from_millis(200));
        let slept = thread_cpu_s().expect("a thread clock") - before;
        assert!((0.0..0.1).contains(&slept), "{slept} s of CPU asleep");
    }
}
