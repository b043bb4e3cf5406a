//! Laparoscopic Heller myotomy (the esophageal myotomy paper, issue 17): a boundary-element
//! esophagus precomputed once, palpated and grasped at haptic rate, and incised by dividing
//! its surface along the hook's path: the anatomy, palpation, the scenario, the procedure
//! (task, metrics, drawing) and its registry entry.

pub mod anatomy;
mod bench;
mod drawing;
mod field;
#[cfg(test)]
mod palpation_tests;
mod plugin;
mod precompute;
mod procedure;
pub mod scenario;

pub use plugin::{INFO, build_procedure, cache_file, score};
pub use precompute::PRECOMPUTE;
pub use procedure::{BAND_M, Metrics, Myotomy, STEPS};
pub use scenario::Scenario;
