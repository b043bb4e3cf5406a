//! How snapshots reach the renderers: the [`SnapshotBus`] holds the newest, and a
//! [`SnapshotJob`] lets a procedure read what it must on the simulation thread and leave the
//! rest of the build (meshes, normals) to the bus's builder thread, so the simulation steps
//! on while the picture is put together. Built snapshots are published in the order they
//! were handed over: a slow build never replaces a newer picture.

use super::{ModelSnapshot, Snapshot};
use arc_swap::ArcSwap;
use std::sync::mpsc::{SyncSender, sync_channel};
use std::sync::{Arc, Condvar, Mutex, PoisonError, Weak};
use std::time::Instant;

/// A value built already, or still to build from what the job owns (read from the
/// simulation already): the build may run on any thread, and gives the same value on every
/// one.
pub struct Job<T>(Build<T>);

enum Build<T> {
    Ready(Box<T>),
    Later(Box<dyn FnOnce() -> T + Send>),
}

impl<T> Job<T> {
    /// A value built already.
    pub fn ready(value: T) -> Self {
        Self(Build::Ready(Box::new(value)))
    }

    /// A value that `build` puts together from what it owns.
    pub fn later(build: impl FnOnce() -> T + Send + 'static) -> Self {
        Self(Build::Later(Box::new(build)))
    }

    /// Whether it is built already.
    pub fn is_ready(&self) -> bool {
        matches!(self.0, Build::Ready(_))
    }

    /// The value (built here, if it was not yet).
    pub fn build(self) -> T {
        match self.0 {
            Build::Ready(v) => *v,
            Build::Later(f) => f(),
        }
    }
}

/// A snapshot, built or still to build.
pub type SnapshotJob = Job<Snapshot>;

/// One model's render mesh, built or still to build ([`super::TissueModel::render_job`]):
/// what a snapshot's job carries of each model.
pub type MeshJob = Job<ModelSnapshot>;

/// Jobs handed to the builder at most before [`SnapshotBus::publish_job`] waits (one being
/// built, one waiting): a builder that falls behind slows the simulation rather than
/// queueing pictures that would be stale when shown.
const QUEUED: usize = 1;

/// Publishes snapshots without blocking: readers load the newest `Arc`, the simulation swaps in
/// a new one (or hands a job to the builder thread, which swaps it in when built).
#[derive(Default)]
pub struct SnapshotBus {
    current: ArcSwap<Snapshot>,
    order: Mutex<Order>,
    /// Signalled whenever a job is done.
    settled: Condvar,
    /// Started with the first job that is not built yet.
    builder: Mutex<Option<SyncSender<(u64, SnapshotJob)>>>,
}

/// Snapshots handed over (each gets the next number), the number of the one showing, the
/// jobs not yet done, and the builder's times.
#[derive(Default)]
struct Order {
    handed: u64,
    showing: u64,
    building: usize,
    build_s: Vec<f64>,
}

impl SnapshotBus {
    pub fn new() -> Self {
        Self::default()
    }

    fn order(&self) -> std::sync::MutexGuard<'_, Order> {
        self.order.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The next number in the order of handing over.
    fn hand(&self) -> u64 {
        let mut o = self.order();
        o.handed += 1;
        o.handed
    }

    /// Shows snapshot number `n` unless a later one shows already.
    fn show(&self, n: u64, s: Snapshot) {
        let mut o = self.order();
        if n > o.showing {
            o.showing = n;
            self.current.store(Arc::new(s));
        }
    }

    pub fn publish(&self, s: Snapshot) {
        let n = self.hand();
        self.show(n, s);
    }

    /// Publishes `job`'s snapshot: at once where it is built, else once the builder thread
    /// has built it (this waits only while the builder still has a job waiting). Where no
    /// builder thread can be started, it is built here.
    pub fn publish_job(self: &Arc<Self>, job: SnapshotJob) {
        if job.is_ready() {
            self.publish(job.build());
            return;
        }
        let n = self.hand();
        let mut builder = self.builder.lock().unwrap_or_else(PoisonError::into_inner);
        if builder.is_none() {
            *builder = start_builder(Arc::downgrade(self));
        }
        let Some(to) = builder.as_ref() else {
            drop(builder);
            self.show(n, job.build());
            return;
        };
        self.order().building += 1;
        if let Err(e) = to.send((n, job)) {
            // The builder is gone: build it here.
            *builder = None;
            drop(builder);
            self.order().building -= 1;
            self.show(n, (e.0).1.build());
        }
    }

    /// Waits until every job handed over is built and published (or passed over for a
    /// later snapshot).
    pub fn flush(&self) {
        let mut o = self.order();
        while o.building > 0 {
            o = self.settled.wait(o).unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// The builder thread's time on each job since the last call, seconds, in order.
    pub fn take_build_seconds(&self) -> Vec<f64> {
        std::mem::take(&mut self.order().build_s)
    }

    pub fn latest(&self) -> Arc<Snapshot> {
        self.current.load_full()
    }
}

/// The builder thread of the bus `bus`: it builds the jobs in the order handed over, on a
/// pool of its own thread (a build's parallel loops run there in order, beside the
/// simulation's pool rather than in it), and ends with the bus. None where no thread could
/// be started.
fn start_builder(bus: Weak<SnapshotBus>) -> Option<SyncSender<(u64, SnapshotJob)>> {
    let (to, jobs) = sync_channel::<(u64, SnapshotJob)>(QUEUED);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(|_| "snapshot build".into())
        .build()
        .ok()?;
    std::thread::Builder::new()
        .name("snapshots".into())
        .spawn(move || {
            for (n, job) in jobs {
                let t0 = Instant::now();
                let s = pool.install(|| job.build());
                let secs = t0.elapsed().as_secs_f64();
                let Some(bus) = bus.upgrade() else {
                    return;
                };
                bus.show(n, s);
                let mut o = bus.order();
                o.building -= 1;
                o.build_s.push(secs);
                drop(o);
                bus.settled.notify_all();
            }
        })
        .ok()?;
    Some(to)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(step: u64) -> Snapshot {
        Snapshot {
            step,
            ..Default::default()
        }
    }

    #[test]
    fn readers_keep_their_snapshot_while_a_new_one_is_published() {
        let bus = SnapshotBus::new();
        bus.publish(at(1));
        let held = bus.latest();
        let reader = std::thread::scope(|s| {
            s.spawn(|| bus.publish(at(2)));
            s.spawn(|| bus.latest().step).join().unwrap_or(0)
        });
        assert_eq!(held.step, 1);
        assert!(reader == 1 || reader == 2);
        assert_eq!(bus.latest().step, 2);
    }

    #[test]
    fn jobs_are_built_off_the_calling_thread_and_shown_in_the_order_handed_over() {
        let bus = Arc::new(SnapshotBus::new());
        let caller = std::thread::current().id();
        let (gate, wait) = std::sync::mpsc::channel::<()>();
        // A slow build handed over before a snapshot published directly: once built it
        // does not replace the newer one.
        bus.publish_job(SnapshotJob::later(move || {
            let _ = wait.recv();
            at(10)
        }));
        bus.publish(at(11));
        assert_eq!(bus.latest().step, 11);
        let _ = gate.send(());
        bus.flush();
        assert_eq!(bus.latest().step, 11, "the older build was passed over");
        // Builds follow each other in order, on another thread.
        let built_on = Arc::new(Mutex::new(Vec::new()));
        for step in 12..20 {
            let on = built_on.clone();
            bus.publish_job(SnapshotJob::later(move || {
                on.lock().expect("lock").push(std::thread::current().id());
                at(step)
            }));
        }
        bus.flush();
        assert_eq!(bus.latest().step, 19);
        let on = built_on.lock().expect("lock");
        assert_eq!(on.len(), 8);
        assert!(on.iter().all(|&t| t != caller));
        assert_eq!(bus.take_build_seconds().len(), 9);
        assert!(bus.take_build_seconds().is_empty());
        // A built job is shown at once.
        bus.publish_job(SnapshotJob::ready(at(20)));
        assert_eq!(bus.latest().step, 20);
    }
}
