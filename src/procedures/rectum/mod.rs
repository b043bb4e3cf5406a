//! Laparoscopic rectum dissection (rectum paper, issue 14): the bowel as a Cosserat rod, the
//! tissue around it as the four-layer membrane, dissected by cutting the springs of the plane
//! between layers 2 and 3: the anatomy, the rod with its skin, the scene that steps them with
//! the membrane and the instruments, and the procedure (scenario, task, metrics, drawing).

pub mod anatomy;
mod cases;
mod coupling;
mod drawn;
mod field;
mod gpu_bench;
mod plugin;
mod procedure;
pub mod regions;
#[cfg(test)]
mod rod_tests;
pub mod scenario;
pub mod scene;
#[cfg(test)]
mod tests;

pub use anatomy::{Anatomy, AnatomyError, AnatomyParams};
pub use plugin::{INFO, score};
pub use procedure::{JUMP_M, Metrics, Rectum, STEPS};
pub use scenario::Scenario;
pub use scene::{RectumScene, SceneError, SceneParams, StepOutcome, ToolState};
