//! Medical imaging the simulator renders on the CPU: the X-ray projection a fluoroscope makes
//! (`xray`), for the interventional procedures.

pub mod xray;
