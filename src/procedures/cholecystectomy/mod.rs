//! Laparoscopic cholecystectomy (the cholecystectomy paper, issue 16): shape-matching organs,
//! the cloth and adhesive fascia between gallbladder and liver, clips and cuts in Calot's
//! triangle: the anatomy, the scene that steps its particle world, clips and cuts, the
//! procedure (scenario, task, metrics, drawing) and its registry entry.

pub mod anatomy;
mod cases;
pub mod clips;
mod drawing;
mod field;
mod gpu_bench;
mod plugin;
mod procedure;
pub mod scenario;
pub mod scene;

pub use anatomy::{Anatomy, AnatomyError, AnatomyParams};
pub use plugin::{INFO, build_procedure, score};
pub use procedure::{Cholecystectomy, Metrics, RightTool, STEPS};
pub use scenario::Scenario;
