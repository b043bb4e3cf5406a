//! Interventional catheterisation (the catheter paper, issue 18): the skeleton-spring
//! catheter and vessel tree of [`crate::models::skeleton`] under a force-feedback
//! handle, under fluoroscopy: the scenario, the procedure (task, metrics, events, drawing),
//! the fluoroscope and contrast (`fluoroscopy`) and its registry entry.

mod bench;
mod field;
pub mod fluoroscopy;
mod plugin;
mod procedure;
pub mod scenario;
pub mod tree_table;
pub mod wire_table;

pub use plugin::{INFO, build_procedure, build_scene, score};
pub use procedure::{Catheterisation, Metrics, STEPS};
pub use scenario::Scenario;
