//! Medical imaging the simulator renders on the CPU: the X-ray projection a fluoroscope makes
//! (`xray`) and the contrast medium that makes the vessels show in it (`contrast`), for the
//! interventional procedures.

pub mod contrast;
pub mod xray;
