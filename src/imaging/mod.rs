//! Medical imaging the simulator renders on the CPU: the X-ray projection a fluoroscope makes
//! (`xray`), the fluoroscope around it (`fluoro`: the C-arm, pulses, dose, collimation,
//! roadmap, the monitor's picture) and the contrast medium that makes the vessels show in it
//! (`contrast`), for the interventional procedures.

pub mod contrast;
pub mod fluoro;
pub mod xray;
