//! The desktop: the supervisor's window with its panels, the simulation thread behind it, and
//! the desktop laparoscope camera.

pub mod dashboard;
pub mod desktop;
pub mod learning;
pub mod runner;
pub mod screens;
pub mod window;
