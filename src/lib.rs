//! Vesalius: a virtual-reality trainer for minimally invasive surgery.
#![forbid(unsafe_code)]
// Index loops over parallel arrays (points, normals, flags) read clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod assess;
pub mod collision;
pub mod diagnostics;
pub mod gpu;
pub mod haptics;
pub mod imaging;
pub mod input_error;
pub mod mesh;
pub mod models;
pub mod params;
pub mod procedures;
pub mod profiler;
pub mod progress;
pub mod records;
pub mod registry;
pub mod render;
pub mod rng;
pub mod scenario;
pub mod session;
pub mod sim;
#[cfg(test)]
mod testing;
pub mod trace;
pub mod ui;
pub mod verify;
pub mod xr;
