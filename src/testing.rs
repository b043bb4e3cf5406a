//! Helpers for the crate's own tests, below every module so that any may use them.

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
