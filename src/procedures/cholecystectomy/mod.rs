//! Laparoscopic cholecystectomy (the cholecystectomy paper): shape-matching organs, the cloth
//! and adhesive fascia between gallbladder and liver, clips and cuts in Calot's triangle.
//! Issue 16, in progress: the anatomy here; the scene, the procedure and its registry entry
//! follow.

pub mod anatomy;
pub mod clips;
pub mod scene;

pub use anatomy::{Anatomy, AnatomyError, AnatomyParams};
