//! Esophageal Heller myotomy (the myotomy paper): a boundary-element esophagus precomputed
//! once, palpated and incised. Not yet a registered procedure: its model comes first.

pub mod anatomy;
pub mod palpation;
mod precompute;

pub use precompute::PRECOMPUTE;
