//! Laparoscopic rectum dissection (rectum paper, issue 14): the bowel as a Cosserat rod, the
//! tissue around it as the four-layer membrane, dissected by cutting the springs of the plane
//! between layers 2 and 3. This folder grows into the procedure; today it holds the anatomy, the rod with its
//! skin, and the scene that steps them with the membrane and the instruments.

pub mod anatomy;
pub mod regions;
pub mod rod;
pub mod scene;
pub mod skin;
#[cfg(test)]
mod tests;

pub use anatomy::{Anatomy, AnatomyError, AnatomyParams};
pub use scene::{RectumScene, SceneError, SceneParams, StepOutcome, ToolState};
