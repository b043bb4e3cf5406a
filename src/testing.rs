//! Helpers for the crate's own tests, below every module so that any may use them.

use std::collections::BTreeMap;
use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};

/// Runs `f` on a pool of `threads` workers (tests comparing the bytes of 1 and 2 threads).
pub(crate) fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}

/// A sandbox tree fixed for the tests that compute scores by hand (the shipped tree's
/// references are calibrated from sessions and change with them): time 10 s expert, 40 s
/// novice (weight 0.3), grasper overloads 0 and 3 (0.3), the task's steps (0.4).
pub(crate) const SANDBOX_TREE: &str = r#"procedure = "sandbox"
version = 1
title = "Basic skill"

[[node]]
path = "efficiency"
weight = 0.3

[[node]]
path = "efficiency/completion_time"
metric = "completion_time_s"
better = "lower"
expert = 10.0
novice = 40.0
weight = 1.0

[[node]]
path = "safety"
weight = 0.3

[[node]]
path = "safety/grasper_overloads"
text = "Times the grasper's force went over its full scale"
metric = "grasper_overloads"
better = "lower"
expert = 0.0
novice = 3.0
weight = 1.0

[[node]]
path = "quality"
weight = 0.4

[[node]]
path = "quality/task_steps"
metric = "session.steps_fraction"
better = "higher"
expert = 1.0
novice = 0.0
weight = 1.0
"#;

/// A scratch folder, removed when the test passes (kept when it fails, to look at).
pub(crate) struct Scratch(PathBuf);

impl Scratch {
    /// A fresh, empty folder `vesalius-{group}-{pid}-{name}` in the system's temporary folder
    /// (the test's own: no other test of the binary may use the same `group` and `name`).
    pub(crate) fn new(group: &str, name: &str) -> Scratch {
        let d =
            std::env::temp_dir().join(format!("vesalius-{group}-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("scratch folder");
        Scratch(d)
    }
}

impl Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// The folders [`SharedScratch`] hands out: how many tests hold each now, and whether one of
/// them failed.
static SHARED: Mutex<BTreeMap<PathBuf, (usize, bool)>> = Mutex::new(BTreeMap::new());

/// A scratch folder that several tests of the binary use at once (a cache they share): each
/// holds one of these to its end, and the last to let go removes the folder, unless one of
/// them failed (then it stays, to look at). A test that starts after that makes it afresh.
pub(crate) struct SharedScratch(PathBuf);

impl SharedScratch {
    /// The folder `vesalius-{group}-{pid}` in the system's temporary folder, made if missing.
    pub(crate) fn new(group: &str) -> SharedScratch {
        let d = std::env::temp_dir().join(format!("vesalius-{group}-{}", std::process::id()));
        shared().entry(d.clone()).or_default().0 += 1;
        // Held: no other test removes it now.
        let made = std::fs::create_dir_all(&d);
        let s = SharedScratch(d);
        made.expect("scratch folder");
        s
    }
}

fn shared() -> MutexGuard<'static, BTreeMap<PathBuf, (usize, bool)>> {
    SHARED.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Deref for SharedScratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for SharedScratch {
    fn drop(&mut self) {
        let mut held = shared();
        let Some((users, failed)) = held.get_mut(&self.0) else {
            return;
        };
        *users -= 1;
        *failed |= std::thread::panicking();
        if *users == 0 && !*failed {
            let _ = std::fs::remove_dir_all(&self.0);
            held.remove(&self.0);
        }
    }
}
